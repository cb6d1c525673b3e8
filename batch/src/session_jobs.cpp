// The jobs over recorded sessions: identify, discover and qc, one session an item. A qc job records
// its decisions in the job's QC history, where the line's own decisions are.
#include <fmt/format.h>

#include <chrono>
#include <cmath>
#include <map>

#include "jobs_internal.h"
#include "strut/ident/discover.h"
#include "strut/ident/session_fit.h"
#include "strut/qc/decision.h"
#include "strut/qc/history.h"
#include "strut/report/qc_report.h"
#include "strut/sim/drop_fit.h"

namespace strut::batch {
namespace {

nlohmann::json Number(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }

double SecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

//! The fit's estimates and noise ratios.
nlohmann::json FitJson(const ident::FitSummary& s) {
  nlohmann::json estimates = nlohmann::json::object(), noise = nlohmann::json::object();
  for (int i : s.estimated_positions)
    estimates[s.parameters.spec(i).key()] = {{"value", Number(s.parameters.value(i))}, {"sd", Number(s.estimates[i].sd)}};
  for (const auto& [channel, ratio] : ident::PooledNoiseRatio(s)) noise[channel] = Number(ratio);
  return {{"model", s.model},          {"converged", s.converged}, {"iterations", s.iterations},
          {"verdict", ident::ToString(s.Verdict())}, {"estimate", estimates}, {"noise_ratio", noise}};
}

class SessionJob : public JobRunner {
 public:
  SessionJob(const JobSpec& job, std::string batch_id) : job_(job), batch_id_(std::move(batch_id)) {
    options_.composition = job.model;
    options_.causality = ident::ParseCausality(job.input);
    // As strut identify: drop experiments are fitted beside the periodic ones.
    if (job.kind == "identify") options_.estimator.transient_predictor = sim::DropPredictorFactory();
    if (job.kind == "qc") reference_ = qc::ReadReference(job.reference);
  }

  nlohmann::json RunItem(int index) const override {
    const std::string& session = job_.sessions.at(index);
    const auto start = std::chrono::steady_clock::now();
    nlohmann::json record{{"session", session}};
    if (job_.kind == "qc") {
      const qc::Decision d = qc::RunQc(session, reference_);
      record["decision"] = report::QcToJson(d);
      record["decision"].erase("seconds");
      if (!job_.db.empty()) {
        qc::History history(job_.db);
        record["recorded"] = history.Record(d, "", DecisionKey(batch_id_, job_.name, session)).inserted;
      }
    } else {
      const ident::Model model = ident::Model::Build(job_.model, options_.causality);
      ident::SessionFitOptions options = options_;
      options.estimator.n = ident::FitGridPoints(0, options.estimator.scheme, options.causality);
      ident::FitData data = ident::ReadFitData({session}, model, options.estimator.n);
      if (job_.kind == "identify") {
        record["fit"] = FitJson(ident::FitPrepared(std::move(data), model, options).summary);
      } else {
        ident::DiscoverOptions discover;
        discover.threads = 1;  // the batch runs shards side by side instead
        const ident::DiscoveryResult r = ident::Discover(data, options, discover);
        nlohmann::json steps = nlohmann::json::array();
        for (const auto& s : r.steps) steps.push_back({{"term", s.term}, {"delta_bic", s.delta_bic}});
        record["discovery"] = {{"missing", r.missing}, {"final_model", r.final_model},
                               {"nothing_missing", r.nothing_missing}, {"steps", steps},
                               {"final_fit", FitJson(r.final_fit)}};
      }
    }
    record["timing"] = {{"seconds", SecondsSince(start)}};
    return record;
  }

  std::string Table(const std::vector<nlohmann::json>& records, bool complete) const override {
    std::string text = fmt::format("{} of {} sessions ({}):\n", job_.kind, job_.sessions.size(), job_.name);
    std::map<std::string, long> counts;
    for (const nlohmann::json& r : records) {
      std::string what;
      if (job_.kind == "qc") {
        const nlohmann::json& d = r.at("decision");
        what = fmt::format("{:<9} {:<20} {}", d.at("verdict").get<std::string>(), d.at("serial").get<std::string>(),
                           d.at("reasons").empty() ? "" : d.at("reasons").front().get<std::string>());
        ++counts[d.at("verdict").get<std::string>()];
      } else if (job_.kind == "identify") {
        what = r.at("fit").at("verdict").get<std::string>();
        ++counts[what];
      } else {
        const nlohmann::json& m = r.at("discovery").at("missing");
        for (const auto& t : m) what += (what.empty() ? "+" : " +") + t.get<std::string>();
        if (what.empty()) what = "(nothing missing)";
        ++counts[m.empty() ? "nothing missing" : "terms found"];
      }
      text += fmt::format("  {:<60} {}\n", r.at("session").get<std::string>(), what);
    }
    std::string summary;
    for (const auto& [k, n] : counts) summary += fmt::format("{}{} {}", summary.empty() ? "" : ", ", n, k);
    text += fmt::format("{} sessions: {}\n", records.size(), summary.empty() ? "none" : summary);
    if (!complete) text += fmt::format("INCOMPLETE: {} of {} sessions\n", records.size(), job_.sessions.size());
    return text;
  }

  std::string ItemName(int index) const override { return job_.sessions.at(index); }

 private:
  JobSpec job_;
  std::string batch_id_;
  ident::SessionFitOptions options_;
  qc::Reference reference_;
};

}  // namespace

std::unique_ptr<JobRunner> MakeSessionRunner(const JobSpec& job, const std::string& batch_id) {
  return std::make_unique<SessionJob>(job, batch_id);
}

std::unique_ptr<JobRunner> MakeRunner(const JobSpec& job, const std::string& batch_id) {
  return job.IsStudy() ? MakeStudyRunner(job) : MakeSessionRunner(job, batch_id);
}

std::string DecisionKey(const std::string& batch_id, const std::string& job, const std::string& session) {
  return fmt::format("batch:{}:{}:{}", batch_id, job, session);
}

}  // namespace strut::batch
