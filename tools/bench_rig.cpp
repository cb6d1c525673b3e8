// strut bench rig: the standard matrix through the real drivers on the simulated rig served in this
// process (what `strut rig run --rig sim` runs: sim::RigServer, Modbus TCP, CAN frames over UDP
// loopback, rig::MatrixRunner, the recorder) at several clock speeds, side by side with
// `strut sim matrix` (sim::SimulatedRig::RunMatrix) on the same truth: wall and CPU time per
// simulated second, and the fastest speed that keeps up. docs/rig-run.md "Benchmark".
#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>
#include <optional>

#include "commands.h"
#include "option_checks.h"
#include "output_files.h"
#include "strut/daq/rig_devices.h"
#include "strut/daq/session.h"
#include "strut/rig/campaign.h"
#include "strut/rig/matrix_runner.h"
#include "strut/sim/recorded_truth.h"
#include "strut/sim/rig_server.h"
#include "strut/sim/simulated_rig.h"
#include "strut/study/cpu_time.h"
#include "strut/study/rig_speed.h"
#include "truth_options.h"

namespace strut::tools {
namespace {

using Clock = std::chrono::steady_clock;

double Since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

struct BenchRig {
  TruthOptions truth_options;
  std::vector<double> speeds{25, 50, 100, 200, 400};
  int repeats = 1;
  unsigned long seed = 1;
  std::string dir, json_path;

  //! The default: a drawn unit behind calibrated transducers and an ideal actuator, as the
  //! end-to-end test runs (tests/test_rig_sim_end_to_end.cpp); a --truth file is taken as it is.
  sim::Truth Truth() const {
    TruthOptions o = truth_options;
    const bool built_in = o.truth_path.empty();
    if (built_in) {
      if (!o.draw_seed) o.draw_seed = 1001;
      o.ideal_actuator = true;
    }
    sim::Truth truth = o.Load();
    if (built_in) {
      for (sim::SensorOptions* s : {&truth.sensors.stroke, &truth.sensors.force, &truth.sensors.pressure}) {
        s->offset = 0.0;
        s->gain_error = 0.0;
      }
    }
    return truth;
  }

  study::RigRunFigures RunRig(const sim::Truth& truth, const rig::MatrixPlan& plan, double speed, const std::string& path) const {
    rig::RunnerOptions options;
    options.periods = plan.periods.value_or(3);
    options.stream_speed = speed;
    const rig::SafetyConfig safety;
    std::vector<rig::RunItem> items;
    for (const rig::MatrixEntry& e : plan.experiments) items.push_back({e});
    study::RigRunFigures f;
    const double cpu0 = study::ProcessSeconds();
    const auto t0 = Clock::now();
    {
      daq::RigConnection connection;
      connection.controller = "sim";
      const sim::SimulatedRigFactory served(truth, speed);
      const daq::RigDevices devices = served.Connect(connection);
      daq::RecorderOptions ro;
      ro.force = true;
      daq::RecordingMetadata metadata = rig::RunMetadata(truth.damper_serial, "strut bench rig", "", "standard", safety);
      metadata.groups = sim::TruthMetadata(truth);
      daq::Recorder recorder = daq::Recorder::Open(path, metadata, ro);
      rig::MatrixRunner runner(*devices.controller, *devices.acquisition, recorder, safety, options);
      const rig::RunReport report = runner.Run(items);
      recorder.Close();
      const sim::RigServerStats stats = sim::ServedRig(devices)->stats();
      f.simulated = stats.simulated_seconds;
      f.plant_cpu = stats.compute_seconds;
      f.max_lateness = stats.max_lateness;
      const daq::AcquisitionStats& a = devices.acquisition->stats();
      f.lost_sets = a.lost_sample_sets;
      f.gaps = a.gaps;
      f.refused_frames = a.ahead_of_clock + a.late_frames + a.corrupt_frames;
      f.finished = report.outcome == rig::RunOutcome::kComplete;
      f.complete = report.complete.size();
      f.not_steady = report.not_steady.size();
      f.aborted = report.aborted.size();
      if (!f.finished) spdlog::warn("{}x: the run ended {}: {}", speed, rig::ToString(report.outcome), report.cause);
    }  // the drivers and the served rig stop here: their threads count to the run
    f.wall = Since(t0);
    f.cpu = study::ProcessSeconds() - cpu0;
    f.recorded = study::RecordedSeconds(daq::ReadSession(path));  // also the contract check
    std::filesystem::remove(path);
    std::filesystem::remove(daq::JournalPath(path));
    return f;
  }

  void Run() const {
    namespace fs = std::filesystem;
    const fs::path folder = dir.empty() ? fs::temp_directory_path() : fs::path(dir);
    if (!fs::is_directory(folder)) throw std::invalid_argument(fmt::format("--dir {}: not a directory", folder.string()));
    const sim::Truth truth = Truth();
    const rig::MatrixPlan plan = rig::StandardMatrixPlan();
    const std::size_t n = plan.experiments.size();
    const std::string path = (folder / fmt::format("strut-bench-rig-{}.h5", ::getpid())).string();

    // (b) strut sim matrix on the same truth, as often as each speed runs (medians).
    const study::SimMatrixTiming matrix = study::TimeSimMatrix(truth, plan, seed, repeats, path);
    const double matrix_wall = matrix.wall, matrix_cpu = matrix.cpu;
    const double matrix_simulated = matrix.simulated, matrix_recorded = matrix.recorded;

    // (a) the matrix through the drivers, at each speed.
    std::vector<study::RigSpeedRow> rows;
    for (double speed : speeds) {
      std::vector<study::RigRunFigures> runs;
      for (int k = 0; k < repeats; ++k) {
        spdlog::info("bench rig: {}x, run {} of {}", speed, k + 1, repeats);
        runs.push_back(RunRig(truth, plan, speed, path));
      }
      rows.push_back(study::SummariseSpeed(speed, std::move(runs), n));
    }

    const double matrix_cpu_per_sim = matrix_cpu / matrix_simulated;
    std::cout << fmt::format(
        "rig bench: the standard matrix ({} experiments) of {} ({}), {} run{} per speed (medians), one process on "
        "this machine\n\n",
        n, truth.BuildModel(ident::Causality::kStrokeInput).composition(), truth.source, repeats,
        repeats > 1 ? "s" : "");
    std::cout << fmt::format("strut sim matrix (sim::SimulatedRig::RunMatrix + write): {:.1f} s simulated ({:.1f} s "
                             "recorded) in {:.2f} s wall, {:.2f} s CPU: {:.0f} simulated s per CPU s, {:.2f} CPU ms per "
                             "simulated s\n\n",
                             matrix_simulated, matrix_recorded, matrix_wall, matrix_cpu, 1.0 / matrix_cpu_per_sim,
                             1e3 * matrix_cpu_per_sim);
    std::cout << fmt::format("{:>6} {:>7} {:>7} {:>7} {:>8} {:>7} {:>9} {:>9} {:>8} {:>8} {:>6} {:>5} {:>8} {:>7} {:>8} {:>8} "
                             "{:>7} {:>7}\n",
                             "speed", "wall s", "CPU s", "plant", "sim s", "rec s", "sim/wall", "sim/CPU", "behind",
                             "complete", "lost", "gaps", "refused", "kept up", "CPUms/s", "x matrix", "CPU x", "wall x");
    nlohmann::json json;
    json["truth"] = truth.source;
    json["composition"] = truth.BuildModel(ident::Causality::kStrokeInput).composition();
    json["experiments"] = n;
    json["repeats"] = repeats;
    json["sim_matrix"] = {{"wall_s", matrix_wall},
                          {"cpu_s", matrix_cpu},
                          {"simulated_s", matrix_simulated},
                          {"recorded_s", matrix_recorded},
                          {"simulated_per_cpu_s", 1.0 / matrix_cpu_per_sim}};
    const std::optional<double> fastest = study::FastestKeptUp(rows);
    for (const study::RigSpeedRow& row : rows) {
      const double wall = row.wall, cpu = row.cpu, simulated = row.simulated;
      // CPU per simulated second against sim matrix's; wall time for a session against its wall time.
      const double cpu_ratio = (cpu / simulated) / matrix_cpu_per_sim;
      const double session_cpu_ratio = cpu / matrix_cpu;
      const double wall_ratio = wall / matrix_wall;
      std::cout << fmt::format("{:>5g}x {:>7.1f} {:>7.1f} {:>7.1f} {:>8.0f} {:>7.0f} {:>9.1f} {:>9.1f} {:>8.2f} {:>5}/{:<2} "
                               "{:>6} {:>5} {:>8} {:>3}/{:<3} {:>8.2f} {:>8.1f} {:>7.1f} {:>7.1f}\n",
                               row.speed, wall, cpu, row.plant, simulated, row.recorded, row.per_wall, row.per_cpu,
                               row.behind, row.complete, n, row.lost, row.gaps, row.refused, row.kept, row.runs.size(),
                               1e3 * cpu / simulated, cpu_ratio, session_cpu_ratio, wall_ratio);
      nlohmann::json runs = nlohmann::json::array();
      for (const study::RigRunFigures& f : row.runs) {
        runs.push_back({{"wall_s", f.wall},          {"cpu_s", f.cpu},           {"plant_cpu_s", f.plant_cpu},
                        {"simulated_s", f.simulated}, {"recorded_s", f.recorded}, {"complete", f.complete},
                        {"not_steady", f.not_steady}, {"aborted", f.aborted},     {"finished", f.finished},
                        {"lost_sets", f.lost_sets},   {"gaps", f.gaps},           {"refused_frames", f.refused_frames},           {"max_lateness_s", f.max_lateness},
                        {"kept_up", f.kept_up(n)}});
      }
      json["speeds"].push_back({{"speed", row.speed},
                                {"wall_s", wall},
                                {"cpu_s", cpu},
                                {"plant_cpu_s", row.plant},
                                {"simulated_s", simulated},
                                {"recorded_s", row.recorded},
                                {"simulated_per_wall_s", row.per_wall},
                                {"simulated_per_cpu_s", row.per_cpu},
                                {"max_lateness_s", row.behind},
                                {"kept_up", row.kept_up()},
                                {"cpu_per_simulated_s_vs_sim_matrix", cpu_ratio},
                                {"cpu_vs_sim_matrix", session_cpu_ratio},
                                {"wall_vs_sim_matrix", wall_ratio},
                                {"runs", runs}});
    }
    std::cout << fmt::format(
        "\nsim s: the served rig's clock (moves, settling, records); rec s: seconds in the session; plant: CPU s of the "
        "simulation thread;\nbehind: s the stream was ever late; lost, gaps, refused: the worst run's lost sample sets, gaps "
        "and frames the receiver refused (ahead of its clock, late or corrupt);\nkept up: runs with all {} experiments complete and "
        "steady, no lost sample set, no gap, never 0.5 s behind;\nCPUms/s: CPU ms per simulated s; x matrix: that against sim matrix's; "
        "CPU x, wall x: CPU and wall time for the session against sim matrix's.\nfastest speed that kept up: {}\n",
        n, fastest ? fmt::format("{:g}x", *fastest) : "none");
    json["fastest_kept_up"] = fastest ? nlohmann::json(*fastest) : nlohmann::json(nullptr);
    if (!json_path.empty()) {
      WriteJsonOutput(json_path, json);
    }
  }
};

}  // namespace

void RegisterBenchRig(CLI::App& bench) {
  auto [sub, command] = AddCommand<BenchRig>(
      bench, "rig",
      "The standard matrix through the real drivers on the simulated rig at several clock speeds, side by "
      "side with strut sim matrix on the same truth: wall and CPU per simulated second");
  command->truth_options.Add(*sub, /*with_actuator=*/true);
  sub->add_option("--speeds", command->speeds, "Simulated seconds per wall second to run at, comma-separated.")
      ->delimiter(',')
      ->check(Between(0.01, 1000.0))
      ->capture_default_str();
  sub->add_option("--repeats", command->repeats, "Runs per speed (the table gives medians).")
      ->check(Between(1, 100))
      ->capture_default_str();
  sub->add_option("--seed", command->seed, "The seed of sim matrix's noise and start phases.")->capture_default_str();
  sub->add_option("--dir", command->dir, "Directory of the temporary sessions (default: the temp directory).");
  sub->add_option("--json", command->json_path, "Also write the figures as JSON.");
  sub->footer("Without --truth: the built-in truth with calibrated transducers (no zero or gain error), drawn with "
                "--draw (default 1001), ideal actuator, as tests/test_rig_sim_end_to_end.cpp runs it.");
}

}  // namespace strut::tools
