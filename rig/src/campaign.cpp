// What a matrix run settles before the rig moves (campaign.h).
#include "strut/rig/campaign.h"

#include <spdlog/fmt/fmt.h>
#include <spdlog/spdlog.h>

#include <cmath>
#include <filesystem>
#include <stdexcept>

namespace strut::rig {

OutputState OutputState::Of(const std::string& output) {
  OutputState s;
  s.journal = daq::JournalPath(output);
  s.session_exists = std::filesystem::exists(output);
  s.journal_exists = std::filesystem::exists(s.journal);
  return s;
}

// The messages name the command-line options because `strut rig run` is the one place a start is
// asked for; each says which option does what the user wants instead.
void CheckStart(const RunStart& start, const OutputState& output) {
  if (start.resume) {
    if (start.force) throw std::invalid_argument("--resume and --force: a resume keeps what was recorded; give one");
    if (!output.journal_exists) {
      throw std::invalid_argument(fmt::format(
          "--resume: {} has no journal {} to go on from{}", start.output, output.journal,
          output.session_exists ? " (the session was completed, or recorded without keeping it)" : ""));
    }
    return;
  }
  if (output.journal_exists && !start.force)
    throw std::invalid_argument(fmt::format("-o {}: the journal {} of an interrupted run is there: --resume it, "
                                            "`strut recover` it, or give --force to start over",
                                            start.output, output.journal));
  if (start.serial.empty()) throw std::invalid_argument("--serial: the damper's serial number is needed for a new session");
}

double RunSampleRate(std::optional<double> requested, const MatrixPlan& plan) {
  const double rate = requested.value_or(plan.sample_rate.value_or(200.0));
  if (plan.sample_rate && std::abs(*plan.sample_rate - rate) > 1e-9 * rate)
    throw std::invalid_argument(fmt::format("--daq-rate {} Hz: the matrix {} wants sample_rate {} Hz", rate,
                                            plan.source, *plan.sample_rate));
  return rate;
}

std::vector<RunItem> ExperimentsToRun(const RunStart& start, const std::vector<MatrixEntry>& matrix,
                                      const daq::Session* so_far) {
  if (!start.resume) {
    std::vector<RunItem> items;
    for (const MatrixEntry& e : matrix) items.push_back({e});
    return items;
  }
  if (so_far == nullptr) throw std::invalid_argument(fmt::format("--resume: no session so far for {}", start.output));
  if (!start.serial.empty() && start.serial != so_far->damper_serial)
    throw std::invalid_argument(fmt::format("--serial {}: the session {} is of damper {}", start.serial, start.output,
                                            so_far->damper_serial));
  return RemainingExperiments(matrix, *so_far);
}

void RefuseUnsafeMatrix(const std::vector<RunItem>& items, const SafetyConfig& safety, double sample_rate,
                        const ResponsePredictor& predictor, const std::string& matrix_name,
                        const std::string& limits_name, const std::optional<TopOutOptions>& top_out) {
  std::vector<MatrixEntry> entries;
  for (const RunItem& i : items) entries.push_back(i.entry);
  std::vector<std::string> refusals;
  if (top_out) refusals = CheckTopOut(*top_out, safety);
  for (std::string& r : CheckMatrix(entries, safety, sample_rate, predictor)) refusals.push_back(std::move(r));
  if (refusals.empty()) return;
  throw std::invalid_argument(fmt::format("the matrix {} is refused before the rig moves (limits: {}):\n  {}",
                                          matrix_name, limits_name, fmt::join(refusals, "\n  ")));
}

std::optional<TopOutOptions> TopOutToRun(const RunStart& start, bool requested, const TopOutOptions& options) {
  if (!requested || start.resume) return std::nullopt;
  return options;
}

daq::RecordingMetadata RunMetadata(const std::string& serial, const std::string& rig, const std::string& operator_name,
                                   const std::string& matrix, const SafetyConfig& safety) {
  daq::RecordingMetadata m;
  m.damper_serial = serial;
  m.rig = rig;
  m.operator_name = operator_name;
  m.matrix = matrix;
  m.limits = {{"stroke_min", safety.stroke.lower},      {"stroke_max", safety.stroke.upper},
              {"force_min", safety.force.lower},        {"force_max", safety.force.upper},
              {"pressure_min", safety.pressure.lower},  {"pressure_max", safety.pressure.upper},
              {"following_error", safety.following.max_error}, {"max_velocity", safety.actuator.max_velocity},
              {"max_flow", safety.actuator.max_flow}};
  return m;
}

SafetyConfig RecordedLimits(const daq::Session& session) {
  SafetyConfig config;
  const daq::MetadataGroup* recording = session.find_metadata("recording");
  const daq::MetadataGroup* limits = recording ? recording->find_group("limits") : nullptr;
  const auto take = [limits](ChannelLimit& limit, const char* lower, const char* upper) {
    const std::optional<double> lo = limits ? limits->number(lower) : std::nullopt;
    const std::optional<double> hi = limits ? limits->number(upper) : std::nullopt;
    limit.enabled = lo && hi;
    if (limit.enabled) {
      limit.lower = *lo;
      limit.upper = *hi;
    }
  };
  take(config.stroke, "stroke_min", "stroke_max");
  take(config.force, "force_min", "force_max");
  take(config.pressure, "pressure_min", "pressure_max");
  if (const std::optional<double> following = limits ? limits->number("following_error") : std::nullopt)
    config.following.max_error = *following;
  return config;
}

daq::Recorder OpenRunRecorder(const RunStart& start, const daq::RecordingMetadata& metadata, std::size_t to_run) {
  if (start.resume) {
    daq::Session so_far;
    daq::Recorder recorder = daq::Recorder::Resume(start.output, {}, "strut rig run --resume", &so_far);
    spdlog::info("resuming {}: {} experiments recorded, {} to go", start.output, so_far.experiments.size(), to_run);
    return recorder;
  }
  daq::RecorderOptions options;
  options.force = start.force;
  return daq::Recorder::Open(start.output, metadata, options);
}

void CloseCompletedResume(const std::string& output) {
  daq::Recorder::Resume(output, {}, "strut rig run --resume: nothing left to run").Close();
}

}  // namespace strut::rig
