// strut replay: a recorded session played back through the acquisition interface as the rig's
// stream (docs/replay.md): recorded in-process through the recorder (-o), or sent as CAN frames
// to a transport (--to) where a CanAcquisition receives it.
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <cmath>
#include <filesystem>
#include <iostream>
#include <optional>
#include <span>

#include "commands.h"
#include "option_checks.h"
#include "output_files.h"
#include "strut/daq/replay.h"
#include "strut/rig/steady_state.h"

namespace strut::tools {
namespace {

// The matrix runner's steady-state detector (rig/steady_state.h) re-run on the replayed stream:
// each periodic experiment's blocks cut into whole cycles and judged as the runner judges them live.
class SteadyStateOnReplay : public daq::ReplayObserver {
 public:
  struct Row {
    bool judged = false;  //!< periodic with whole samples per cycle, stroke and force there
    rig::SteadyStateVerdict verdict;
  };

  void BeginExperiment(const daq::ReplayedExperiment& x) override {
    rows_.emplace_back();
    summariser_.reset();
    detector_.reset();
    const auto per_cycle = daq::WholeSamplesPerPeriod(x.stream.sample_rate, x.header.frequency, 2);
    if (x.header.kind != daq::ExperimentKind::kPeriodic || !per_cycle) return;
    stroke_ = force_ = pressure_ = -1;
    for (std::size_t c = 0; c < x.stream.channels.size(); ++c) {
      const std::string& name = x.stream.channels[c].name;
      if (name == "stroke") stroke_ = static_cast<int>(c);
      if (name == "force") force_ = static_cast<int>(c);
      if (name == "pressure") pressure_ = static_cast<int>(c);
    }
    if (stroke_ < 0 || force_ < 0) return;
    summariser_.emplace(*per_cycle);
    detector_.emplace();
    rows_.back().judged = true;
  }
  void Block(const daq::ReplayedExperiment&, const daq::AcquiredBlock& b) override {
    if (!summariser_) return;
    if (b.quality.has(daq::Quality::kSequenceGap)) summariser_->Restart();
    const std::span<const double> pressure =
        pressure_ >= 0 ? std::span<const double>(b.values[pressure_]) : std::span<const double>();
    for (const rig::CycleSummary& c : summariser_->Add(b.time_ns, b.values[stroke_], b.values[force_], pressure))
      detector_->Add(c);
  }
  void EndExperiment(const daq::ReplayedExperiment&) override {
    if (detector_) rows_.back().verdict = detector_->verdict();
  }
  const std::vector<Row>& rows() const { return rows_; }

 private:
  std::vector<Row> rows_;
  std::optional<rig::CycleSummariser> summariser_;
  std::optional<rig::SteadyStateDetector> detector_;
  int stroke_ = -1, force_ = -1, pressure_ = -1;
};

std::string SteadyText(const SteadyStateOnReplay::Row& row) {
  if (!row.judged) return "-";
  return fmt::format("{} ({} cycles)", row.verdict.steady ? "yes" : "no", row.verdict.cycles);
}

struct ReplayCommand {
  std::string file, out, to, speed;
  bool force = false;
  int gzip = 4;

  // --speed: a number > 0 or "max"; the default is as fast as possible in-process, the rig's own
  // pace (1) over a transport, where a receiver must keep up.
  double Speed() const {
    if (speed.empty()) return to.empty() ? 0.0 : 1.0;
    if (speed == "max") return 0.0;
    double value = NAN;
    std::size_t used = 0;
    try {
      value = std::stod(speed, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used != speed.size() || !std::isfinite(value) || value <= 0.0) {
      throw std::invalid_argument(fmt::format(
          "--speed {}: give a number > 0 (recorded seconds per wall second) or 'max' (as fast as possible)", speed));
    }
    return value;
  }

  void Run() {
    daq::ReplayOptions options;
    options.speed = Speed();
    if (!to.empty() && !out.empty()) {
      throw std::invalid_argument(fmt::format(
          "-o {} with --to {}: the receiver at {} records what is sent; -o records an in-process replay", out, to, to));
    }
    if (!to.empty() && options.speed == 0.0) {
      throw std::invalid_argument(fmt::format("--speed max with --to {}: a CAN receiver checks the frames against its "
                                              "clock and would drop them; give a speed (1: the recorded pace)",
                                              to));
    }
    namespace fs = std::filesystem;
    std::error_code ec;
    if (!out.empty()) {
      CheckOutputPath("--out", out, {file}, force);
      if (fs::exists(out, ec) && !force)
        throw std::invalid_argument(fmt::format("--out {}: exists; choose another name or add --force to replace it", out));
    }
    auto replay = daq::ReplayAcquisition::Open(file, options);
    const std::string pace = options.pace();

    daq::ReplayFigures figures;
    SteadyStateOnReplay steady;
    if (!to.empty()) {
      const daq::CanAcquisitionOptions can = daq::ReplayCanOptions(*replay);
      // What a receiver is configured with: the calibration travels only here.
      std::cout << fmt::format("replay {} -> {} {}: {} Hz (the receiver's rate: recorded rate x speed), {} frames, "
                               "module {}\n",
                               file, to, pace, can.sample_rate, can.layout.fd ? "CAN FD" : "classic CAN",
                               can.layout.module);
      for (const daq::ChannelDescriptor& c : can.channels)
        std::cout << fmt::format("  channel {:<10} [{}] = {} + {} x counts, range {} .. {}\n", c.name, c.unit,
                                 c.calibration.offset, c.calibration.gain, c.calibration.range_min,
                                 c.calibration.range_max);
      figures = daq::SendReplay(*replay, daq::OpenCanTransport(to, false, can.layout.fd), can, &steady);
    } else {
      std::cout << fmt::format("replay {}{} {}\n", file, out.empty() ? "" : " -> " + out, pace);
      if (out.empty()) {
        figures = daq::PlayReplay(*replay, nullptr, &steady);
      } else {
        daq::RecorderOptions recorder_options;
        recorder_options.force = force;
        recorder_options.write.gzip_level = gzip;
        daq::Recorder recorder = daq::Recorder::Open(out, daq::ReplayMetadata(replay->session()), recorder_options);
        figures = daq::PlayReplay(*replay, &recorder, &steady);
        recorder.Close();
        daq::ReadSession(out);  // what was written passes the contract check
        spdlog::info("wrote {}", out);
      }
    }
    std::cout << fmt::format("{:<10} {:<9} {:>9} {:>10}  {:<13}  {}\n", "label", "kind", "samples", "end", "counts",
                             "steady (replayed stream)");
    for (std::size_t k = 0; k < replay->experiments().size(); ++k) {
      const daq::ReplayedExperiment& x = replay->experiments()[k];
      std::size_t recorded = 0;
      for (bool r : x.recorded_counts) recorded += r ? 1 : 0;
      std::cout << fmt::format("{:<10} {:<9} {:>9} {:>10}  {:<13}  {}\n", x.header.label,
                               daq::ToString(x.header.kind), x.samples, daq::ToString(x.end),
                               recorded == x.recorded_counts.size() ? "recorded"
                               : recorded == 0                      ? "derived"
                                                                    : "some recorded",
                               k < steady.rows().size() ? SteadyText(steady.rows()[k]) : "-");
      // A session the matrix runner recorded keeps every cycle it saw, settling included
      // (/rig_run/LABEL): the detector re-run on those gives the runner's own verdict.
      const daq::MetadataGroup* run = replay->session().find_metadata("rig_run");
      if (const daq::MetadataGroup* g = run ? run->find_group(x.header.label) : nullptr) {
        const rig::SteadyStateVerdict v = rig::DetectSteadyState(rig::CyclesFromGroup(*g), rig::TolerancesFromGroup(*g));
        std::cout << fmt::format("{:<10} the runner's cycles (/rig_run/{}): steady {} ({} cycles{})\n", "",
                                 x.header.label, v.steady ? "yes" : "no", v.cycles,
                                 v.steady ? fmt::format(", from cycle {}", v.steady_at) : "");
      }
      if (!x.exact_time) {
        spdlog::warn("experiment '{}': its time axis is not on whole nanoseconds (sample rate {} Hz); a recording "
                     "of the replay reproduces it to within 0.5 ns, not bit for bit",
                     x.header.label, x.stream.sample_rate);
      }
    }
    std::cout << fmt::format("{} experiments, {} sample sets, {:.1f} s recorded, played in {:.2f} s\n",
                             figures.experiments, figures.sample_sets, figures.recorded_s, figures.wall_s);
  }
};

}  // namespace

void RegisterReplayCommand(CLI::App& app) {
  auto [sub, command] = AddCommand<ReplayCommand>(
      app, "replay",
      "Play a recorded session back through the acquisition interface as the rig's stream: recorded again "
      "(-o) or sent as CAN frames (--to), docs/replay.md");
  sub->add_option("session", command->file, "The session to play (HDF5).")->required()->check(CLI::ExistingFile);
  sub->add_option("--speed", command->speed,
                  "Recorded seconds per wall second (a number > 0), or max: as fast as possible. Default: max, "
                  "1 with --to.");
  sub->add_option("--to", command->to,
                  "Send the stream as CAN frames to udp:HOST:PORT or can:IFACE instead of recording it here.");
  sub->add_option("-o,--out", command->out, "Record the replay into this session file (HDF5), as a rig run records.");
  sub->add_flag("--force", command->force, "Replace an existing file at the output path.");
  sub->add_option("--gzip", command->gzip, "Compression level 0..9 of the recording.")
      ->check(Between(0, 9))
      ->capture_default_str();
}

}  // namespace strut::tools
