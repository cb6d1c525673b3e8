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

#include "bench_support.h"
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
#include "truth_options.h"

namespace strut::tools {
namespace {

using Clock = std::chrono::steady_clock;

double Since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

//! Seconds the session's experiments hold (samples / rate).
double RecordedSeconds(const daq::Session& s) {
  double seconds = 0.0;
  for (const daq::Experiment& e : s.experiments) seconds += static_cast<double>(e.sample_count()) / e.sample_rate;
  return seconds;
}

//! One run of the matrix through the drivers.
struct RigFigures {
  double wall = 0.0, cpu = 0.0, plant_cpu = 0.0;  //!< s; cpu: the whole process (plant, servers, runner, recorder)
  double simulated = 0.0;                         //!< the served rig's clock, s (moves, settling, records)
  double recorded = 0.0;                          //!< s of samples in the session
  std::size_t complete = 0, not_steady = 0, aborted = 0;
  bool finished = false;  //!< the run ended complete
  std::uint64_t lost_sets = 0, gaps = 0;
  //! Frames the receiver refused: ahead of its clock, late (behind the stream) or corrupt.
  std::uint64_t refused_frames = 0;
  double max_lateness = 0.0;  //!< s the stream was ever behind its schedule
  //! Every experiment complete and steady, nothing lost, and the stream never half a second behind
  //! its schedule (a run that completes slower than asked did not keep up).
  bool kept_up(std::size_t experiments) const {
    return finished && complete == experiments && not_steady == 0 && aborted == 0 && lost_sets == 0 && gaps == 0 &&
           max_lateness <= 0.5;
  }
};

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

  RigFigures RunRig(const sim::Truth& truth, const rig::MatrixPlan& plan, double speed, const std::string& path) const {
    rig::RunnerOptions options;
    options.periods = plan.periods.value_or(3);
    options.stream_speed = speed;
    const rig::SafetyConfig safety;
    std::vector<rig::RunItem> items;
    for (const rig::MatrixEntry& e : plan.experiments) items.push_back({e});
    RigFigures f;
    const double cpu0 = ProcessSeconds();
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
    f.cpu = ProcessSeconds() - cpu0;
    f.recorded = RecordedSeconds(daq::ReadSession(path));  // also the contract check
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

    // (b) strut sim matrix on the same truth: the library call the command makes, and its write;
    // as often as each speed runs (medians).
    std::vector<double> matrix_walls, matrix_cpus;
    double matrix_simulated = 0.0, matrix_recorded = 0.0;  // the same every time: one seed
    for (int k = 0; k < repeats; ++k) {
      const double cpu0 = ProcessSeconds();
      const auto t0 = Clock::now();
      const sim::SimulatedRig simulated(truth);
      sim::RigRunOptions run;
      run.seed = seed;
      std::vector<sim::PeriodicRunReport> reports;
      const daq::Session session = simulated.RunMatrix(plan, run, &reports);
      daq::WriteSession(path, session);
      matrix_walls.push_back(Since(t0));
      matrix_cpus.push_back(ProcessSeconds() - cpu0);
      matrix_simulated = 0.0;
      for (const sim::PeriodicRunReport& r : reports) matrix_simulated += r.simulated_seconds;
      matrix_recorded = RecordedSeconds(session);
      fs::remove(path);
    }
    const double matrix_wall = Median(matrix_walls), matrix_cpu = Median(matrix_cpus);

    // (a) the matrix through the drivers, at each speed.
    struct Row {
      double speed;
      std::vector<RigFigures> runs;
    };
    std::vector<Row> rows;
    for (double speed : speeds) {
      Row row{speed, {}};
      for (int k = 0; k < repeats; ++k) {
        spdlog::info("bench rig: {}x, run {} of {}", speed, k + 1, repeats);
        row.runs.push_back(RunRig(truth, plan, speed, path));
      }
      rows.push_back(std::move(row));
    }

    const auto median = [](const std::vector<RigFigures>& runs, auto field) {
      std::vector<double> v;
      for (const RigFigures& f : runs) v.push_back(field(f));
      return Median(v);
    };
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
    std::optional<double> fastest;
    for (const Row& row : rows) {
      const auto m = [&](auto field) { return median(row.runs, field); };
      const double wall = m([](const RigFigures& f) { return f.wall; });
      const double cpu = m([](const RigFigures& f) { return f.cpu; });
      const double plant = m([](const RigFigures& f) { return f.plant_cpu; });
      const double simulated = m([](const RigFigures& f) { return f.simulated; });
      const double recorded = m([](const RigFigures& f) { return f.recorded; });
      const double behind = m([](const RigFigures& f) { return f.max_lateness; });
      const double per_wall = m([](const RigFigures& f) { return f.simulated / f.wall; });
      const double per_cpu = m([](const RigFigures& f) { return f.simulated / f.cpu; });
      std::size_t complete = n, kept = 0;
      std::uint64_t lost = 0, gaps = 0, refused = 0;
      for (const RigFigures& f : row.runs) {
        complete = std::min(complete, f.complete);
        lost = std::max(lost, f.lost_sets);
        gaps = std::max(gaps, f.gaps);
        refused = std::max(refused, f.refused_frames);
        kept += f.kept_up(n) ? 1 : 0;
      }
      const bool kept_up = kept == row.runs.size();
      if (kept_up && (!fastest || row.speed > *fastest)) fastest = row.speed;
      // CPU per simulated second against sim matrix's; wall time for a session against its wall time.
      const double cpu_ratio = (cpu / simulated) / matrix_cpu_per_sim;
      const double session_cpu_ratio = cpu / matrix_cpu;
      const double wall_ratio = wall / matrix_wall;
      std::cout << fmt::format("{:>5g}x {:>7.1f} {:>7.1f} {:>7.1f} {:>8.0f} {:>7.0f} {:>9.1f} {:>9.1f} {:>8.2f} {:>5}/{:<2} "
                               "{:>6} {:>5} {:>8} {:>3}/{:<3} {:>8.2f} {:>8.1f} {:>7.1f} {:>7.1f}\n",
                               row.speed, wall, cpu, plant, simulated, recorded, per_wall, per_cpu, behind, complete, n,
                               lost, gaps, refused, kept, row.runs.size(), 1e3 * cpu / simulated, cpu_ratio, session_cpu_ratio,
                               wall_ratio);
      nlohmann::json runs = nlohmann::json::array();
      for (const RigFigures& f : row.runs) {
        runs.push_back({{"wall_s", f.wall},          {"cpu_s", f.cpu},           {"plant_cpu_s", f.plant_cpu},
                        {"simulated_s", f.simulated}, {"recorded_s", f.recorded}, {"complete", f.complete},
                        {"not_steady", f.not_steady}, {"aborted", f.aborted},     {"finished", f.finished},
                        {"lost_sets", f.lost_sets},   {"gaps", f.gaps},           {"refused_frames", f.refused_frames},           {"max_lateness_s", f.max_lateness},
                        {"kept_up", f.kept_up(n)}});
      }
      json["speeds"].push_back({{"speed", row.speed},
                                {"wall_s", wall},
                                {"cpu_s", cpu},
                                {"plant_cpu_s", plant},
                                {"simulated_s", simulated},
                                {"recorded_s", recorded},
                                {"simulated_per_wall_s", per_wall},
                                {"simulated_per_cpu_s", per_cpu},
                                {"max_lateness_s", behind},
                                {"kept_up", kept_up},
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
      WriteTextOutput(json_path, json.dump(1) + "\n");
    }
  }
};

}  // namespace

void RegisterBenchRig(CLI::App& bench) {
  auto command = std::make_shared<BenchRig>();
  CLI::App* sub = bench.add_subcommand(
      "rig", "The standard matrix through the real drivers on the simulated rig at several clock speeds, side by "
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
  sub->callback([command] { command->Run(); });
}

}  // namespace strut::tools
