// The drawn-unit studies as batch jobs: an item is one unit, with the study's own seed.
#include <fmt/format.h>

#include "jobs_internal.h"
#include "strut/study/confusion.h"
#include "strut/study/drop.h"
#include "strut/study/lot.h"
#include "strut/study/units.h"

namespace strut::batch {
namespace {

//! Moves `key` of `record` under "timing" (what varies from run to run leaves the results).
nlohmann::json WithTiming(nlohmann::json record, const char* key) {
  record["timing"][key] = record.at(key);
  record.erase(key);
  return record;
}
nlohmann::json WithoutTiming(nlohmann::json record, const char* key) {
  record[key] = record.at("timing").at(key);
  record.erase("timing");
  return record;
}

std::string Incomplete(bool complete, std::size_t have, int of) {
  return complete ? "" : fmt::format("INCOMPLETE: {} of {} units (the table holds those alone)\n", have, of);
}

class ConfusionJob : public JobRunner {
 public:
  explicit ConfusionJob(const JobSpec& job) : job_(job) {
    options_.units = job.units;
    options_.first_seed = job.first_seed;
    options_.base = job.base;
    options_.effects = job.effects;
    options_.servo = job.servo;
    options_.study_sizes = job.sizes == "study";
    for (const std::string& effect : options_.effects)
      if (options_.study_sizes && effect != "none" && !study::FindStudyRange(effect))
        throw BatchError(fmt::format("job {}: effects: no study range for '{}'", job.name, effect));
  }
  nlohmann::json RunItem(int index) const override {
    const study::ConfusionUnit unit = study::RunConfusionUnit(options_, Effect(index), index % options_.units);
    return WithTiming(study::ConfusionUnitJson(unit), "seconds");
  }
  std::string Table(const std::vector<nlohmann::json>& records, bool complete) const override {
    std::vector<study::ConfusionRow> rows;
    std::string text = study::ConfusionHeading(options_);
    for (const std::string& effect : options_.effects) {
      std::vector<study::ConfusionUnit> units;
      for (const nlohmann::json& r : records)
        if (r.at("effect") == effect) units.push_back(study::ConfusionUnitFromJson(WithoutTiming(r, "seconds")));
      if (units.empty()) continue;
      rows.push_back(study::SummariseConfusion(options_, effect, units));
      text += study::ConfusionRowLine(rows.back());
    }
    return text + study::ConfusionDetection(rows) +
           Incomplete(complete, records.size(), job_.Items());
  }
  std::string ItemName(int index) const override {
    return fmt::format("unit {} ({})", options_.first_seed + index % options_.units, Effect(index));
  }

 private:
  const std::string& Effect(int index) const { return options_.effects.at(index / options_.units); }
  JobSpec job_;
  study::ConfusionOptions options_;
};

class UnitsJob : public JobRunner {
 public:
  explicit UnitsJob(const JobSpec& job) : job_(job) {
    options_.units = job.units;
    options_.first_seed = job.first_seed;
    options_.base = job.base;
    options_.servo = job.servo;
    options_.start_off = job.start_off;
    options_.effects = job.effects;
    options_.effects_per_unit = job.effects_per_unit;
    options_.fit_truth = job.fit_truth;
  }
  nlohmann::json RunItem(int index) const override { return study::UnitFitJson(study::FitDrawnUnit(options_, index)); }
  std::string Table(const std::vector<nlohmann::json>& records, bool complete) const override {
    std::vector<study::UnitFit> units;
    std::string text = study::UnitsHeading(options_);
    for (const nlohmann::json& r : records) {
      units.push_back(study::UnitFitFromJson(r));
      text += study::UnitLine(units.back());
    }
    study::UnitsOptions shown = options_;
    shown.units = static_cast<int>(units.size());
    return text + study::UnitsSummary(shown, study::SummariseUnits(std::move(units))) +
           Incomplete(complete, records.size(), job_.Items());
  }
  std::string ItemName(int index) const override { return fmt::format("unit {}", options_.first_seed + index); }

 private:
  JobSpec job_;
  study::UnitsOptions options_;
};

class LotJob : public JobRunner {
 public:
  explicit LotJob(const JobSpec& job) : job_(job) {
    options_.units = job.units;
    options_.first_seed = job.first_seed;
    options_.defect_tenths = job.defects;
    options_.servo = job.servo;
  }
  nlohmann::json RunItem(int index) const override { return study::LotUnitJson(study::DecideLotUnit(options_, index)); }
  std::string Table(const std::vector<nlohmann::json>& records, bool complete) const override {
    std::vector<study::LotUnitResult> units;
    std::string text = study::LotHeading(options_);
    for (const nlohmann::json& r : records) {
      units.push_back(study::LotUnitFromJson(r));
      text += study::LotUnitLine(units.back());
    }
    return text + study::LotSummary(study::SummariseLot(std::move(units))) +
           Incomplete(complete, records.size(), job_.Items());
  }
  std::string ItemName(int index) const override {
    return fmt::format("unit {} ({})", options_.first_seed + index, study::ToString(options_.KindOf(index)));
  }

 private:
  JobSpec job_;
  study::LotOptions options_;
};

class DropJob : public JobRunner {
 public:
  explicit DropJob(const JobSpec& job) : job_(job) {
    options_.units = job.units;
    options_.first_seed = job.first_seed;
    options_.effects = job.effects;
    options_.mass = job.mass;
    options_.velocity = job.velocity;
    options_.duration = job.duration;
  }
  nlohmann::json RunItem(int index) const override { return study::DropUnitJson(study::PredictDropUnit(options_, index)); }
  std::string Table(const std::vector<nlohmann::json>& records, bool complete) const override {
    std::vector<study::DropUnit> units;
    std::string text = study::DropHeading(options_);
    for (const nlohmann::json& r : records) {
      units.push_back(study::DropUnitFromJson(r));
      text += study::DropUnitLine(units.back());
    }
    study::DropOptions shown = options_;
    shown.units = static_cast<int>(units.size());
    return text + study::DropSummary(shown, study::SummariseDrop(std::move(units))) +
           Incomplete(complete, records.size(), job_.Items());
  }
  std::string ItemName(int index) const override { return fmt::format("unit {}", options_.first_seed + index); }

 private:
  JobSpec job_;
  study::DropOptions options_;
};

}  // namespace

std::unique_ptr<JobRunner> MakeStudyRunner(const JobSpec& job) {
  if (job.kind == "confusion") return std::make_unique<ConfusionJob>(job);
  if (job.kind == "qc-lot") return std::make_unique<LotJob>(job);
  if (job.kind == "drop") return std::make_unique<DropJob>(job);
  return std::make_unique<UnitsJob>(job);
}

}  // namespace strut::batch
