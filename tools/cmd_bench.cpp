// strut bench: speed and accuracy figures, measured side by side in one run (medians and ratios).
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <functional>
#include <iostream>
#include <nlohmann/json.hpp>

#include "commands.h"
#include "strut/ident/oscillator.h"
#include "strut/ident/periodic.h"
#include "strut/ident/silverbox.h"
#include "strut/rig/test_matrix.h"
#include "strut/sim/simulated_rig.h"
#include "strut/sim/transient.h"

namespace strut::tools {
namespace {

using Clock = std::chrono::steady_clock;

//! Median wall time (ms) of `repeats` calls.
double MedianMs(int repeats, const std::function<void()>& run) {
  std::vector<double> times;
  for (int i = 0; i < repeats; ++i) {
    const auto start = Clock::now();
    run();
    times.push_back(std::chrono::duration<double, std::milli>(Clock::now() - start).count());
  }
  std::nth_element(times.begin(), times.begin() + times.size() / 2, times.end());
  return times[times.size() / 2];
}

rig::MatrixEntry Experiment(const std::string& label) {
  for (const auto& e : rig::StandardMatrix())
    if (e.label == label) return e;
  throw std::invalid_argument("no experiment " + label);
}

//! The force of the stroke-driven 2 dof solution: the input a force-driven run would be fed.
ident::PeriodicInput ForceInput(const rig::MatrixEntry& e, std::span<const double> theta, int n) {
  ident::PeriodicSolver stroke(ident::Model::Build("2dof", ident::Causality::kStrokeInput));
  const auto s = stroke.Solve(ident::PeriodicInput::Sine(e.frequency, e.static_position, e.amplitude, n), theta);
  ident::PeriodicInput input{e.frequency, {}};
  const Eigen::VectorXd f = s.channel("force");
  input.values.assign(f.data(), f.data() + f.size());
  return input;
}

//! Relative max error of one channel of `s` against the fine reference (grid points nest).
double RelativeError(const ident::PeriodicSolution& s, const Eigen::VectorXd& reference, const char* channel) {
  const Eigen::VectorXd y = s.channel(channel);
  const int stride = static_cast<int>(reference.size() / y.size());
  double error = 0.0;
  for (Eigen::Index mu = 0; mu < y.size(); ++mu) error = std::max(error, std::abs(y[mu] - reference[mu * stride]));
  return error / (reference.maxCoeff() - reference.minCoeff());
}

//! Time to reach 1e-6 relative accuracy: the cheapest periodic-solver setting against integrating
//! transients to steady state with IDA, both causalities, analytic sine inputs (exact for both).
nlohmann::json TimeToAccuracy(const rig::MatrixEntry& b) {
  constexpr double kTarget = 1e-6;
  constexpr int kReferenceN = 25600;
  nlohmann::json rows = nlohmann::json::array();
  std::cout << fmt::format("time to {:.0e} relative accuracy, experiment b (2dof; reference: central4, n = {}):\n",
                           kTarget, kReferenceN);
  for (const ident::Causality causality : {ident::Causality::kStrokeInput, ident::Causality::kForceInput}) {
    const ident::Model model = ident::Model::Build("2dof", causality);
    const std::vector<double> theta = model.defaults().values();
    const bool by_stroke = causality == ident::Causality::kStrokeInput;
    const auto input = [&](int n) {
      return by_stroke ? ident::PeriodicInput::Sine(b.frequency, b.static_position, b.amplitude, n)
                       : ident::PeriodicInput::Sine(b.frequency, 12000.0, 6000.0, n);
    };
    const char* channel = by_stroke ? "force" : "stroke";
    ident::PeriodicSolverOptions reference_options;
    reference_options.scheme = ident::Scheme::kCentral4;
    ident::PeriodicSolver reference_solver(model, reference_options);
    const Eigen::VectorXd reference = reference_solver.Solve(input(kReferenceN), theta).channel(channel);

    // Periodic solver: the cheapest (scheme, n) that reaches the target.
    double periodic_ms = INFINITY;
    std::string periodic_setting = "none";
    for (const ident::Scheme scheme : {ident::Scheme::kBackward2, ident::Scheme::kCentral4, ident::Scheme::kSpectral}) {
      const bool spectral = scheme == ident::Scheme::kSpectral;
      for (int n = spectral ? 16 : 50; n <= (spectral ? 256 : 12800); n *= 2) {
        ident::PeriodicSolverOptions options;
        options.scheme = scheme;
        ident::PeriodicSolver solver(model, options);
        ident::PeriodicSolution s;
        try {
          const double ms = MedianMs(3, [&] { s = solver.Solve(input(n), theta); });
          if (RelativeError(s, reference, channel) <= kTarget) {
            if (ms < periodic_ms) {
              periodic_ms = ms;
              periodic_setting = fmt::format("{} n={}", ident::ToString(scheme), n);
            }
            break;
          }
        } catch (const ident::PeriodicSolverError&) {
        }
      }
    }
    // Transient: the loosest IDA tolerance whose settled last period reaches the target.
    double transient_ms = INFINITY;
    std::string transient_setting = "none";
    for (const double rtol : {1e-6, 1e-7, 1e-8, 1e-9, 1e-10}) {
      sim::TransientOptions options;
      options.rtol = rtol;
      sim::TransientSimulator simulator(model, options);
      sim::SteadyStateOptions steady;
      steady.periods_max = 400;
      steady.relative_floor = 1e-8;
      try {
        sim::PeriodicSteadyStateResult r;
        const double ms = MedianMs(1, [&] { r = simulator.PeriodicSteadyState(theta, input(800), steady); });
        const double error = RelativeError(r.solution, reference, channel);
        if (error <= kTarget) {
          transient_ms = ms;
          transient_setting = fmt::format("rtol {:.0e}, {} periods", rtol, r.periods);
          break;
        }
      } catch (const std::exception& e) {
        spdlog::warn("transient at rtol {:.0e}: {}", rtol, e.what());
      }
    }
    std::cout << fmt::format("  {:<6} input: periodic {:9.3f} ms ({})   transient {:9.1f} ms ({})   ratio {:.0f}\n",
                             ident::ToString(causality), periodic_ms, periodic_setting, transient_ms, transient_setting,
                             transient_ms / periodic_ms);
    rows.push_back({{"input", ident::ToString(causality)},
                    {"periodic_ms", periodic_ms},
                    {"periodic_setting", periodic_setting},
                    {"transient_ms", transient_ms},
                    {"transient_setting", transient_setting},
                    {"ratio", transient_ms / periodic_ms}});
  }
  return rows;
}

struct BenchPeriodic {
  std::string json_path;
  bool quick = false;

  void Run() const {
    nlohmann::json report;
    const ident::Model model = ident::Model::Build("2dof", ident::Causality::kForceInput);
    const std::vector<double> theta = model.defaults().values();
    const rig::MatrixEntry b = Experiment("b");
    const int repeats = quick ? 5 : 21;

    // 1. Cold and warm solves, experiment b, n = 800.
    {
      const ident::PeriodicInput input = ForceInput(b, theta, 800);
      ident::PeriodicSolver solver(model);
      ident::PeriodicSolution cold;
      const double cold_ms = MedianMs(repeats, [&] { cold = solver.Solve(input, theta); });
      std::vector<double> changed = theta;
      for (const char* name : {"theta4", "theta6", "theta16"}) changed[model.defaults().position(name)] *= 1.01;
      ident::PeriodicSolution warm;
      const double warm_ms = MedianMs(repeats, [&] { warm = solver.Solve(input, changed, &cold); });
      std::cout << fmt::format(
          "periodic solve, 2dof force-driven, experiment b, n = 800 (median of {}):\n"
          "  cold  {:8.3f} ms  ({} Newton iterations)   target < 2 ms\n"
          "  warm  {:8.3f} ms  ({} Newton iterations, 1 % change of theta4, theta6, theta16)   target < 0.2 ms\n"
          "  cold / warm = {:.1f}\n",
          repeats, cold_ms, cold.newton_iterations, warm_ms, warm.newton_iterations, cold_ms / warm_ms);
      report["cold_ms"] = cold_ms;
      report["cold_iterations"] = cold.newton_iterations;
      report["warm_ms"] = warm_ms;
      report["warm_iterations"] = warm.newton_iterations;
    }

    // 2. Cost growth with n: time per Newton iteration must grow linearly.
    {
      std::cout << "cost growth with n (2dof force-driven, experiment b, warm start from the same n):\n"
                << fmt::format("  {:>6} {:>12} {:>16} {:>18}\n", "n", "solve ms", "ms / iteration", "per-point ratio");
      nlohmann::json rows = nlohmann::json::array();
      double base_per_point = 0.0;
      for (int n = 100; n <= 12800; n *= 2) {
        const ident::PeriodicInput input = ForceInput(b, theta, n);
        ident::PeriodicSolver solver(model);
        const ident::PeriodicSolution start = solver.Solve(input, theta);
        std::vector<double> changed = theta;
        changed[model.defaults().position("theta4")] *= 1.01;
        ident::PeriodicSolution s;
        const double ms = MedianMs(quick ? 3 : 7, [&] { s = solver.Solve(input, changed, &start); });
        const double per_iteration = ms / std::max(1, s.newton_iterations);
        const double per_point = per_iteration / n;
        if (n == 100) base_per_point = per_point;
        std::cout << fmt::format("  {:>6} {:>12.3f} {:>16.4f} {:>18.2f}\n", n, ms, per_iteration,
                                 per_point / base_per_point);
        rows.push_back({{"n", n}, {"ms", ms}, {"ms_per_iteration", per_iteration},
                        {"per_point_ratio", per_point / base_per_point}});
      }
      report["growth"] = rows;
    }

    // 3. Accuracy against cost per scheme: error of the stroke against a converged reference.
    {
      const int reference_n = 25600;
      ident::PeriodicSolverOptions reference_options;
      reference_options.scheme = ident::Scheme::kCentral4;
      ident::PeriodicSolver reference_solver(model, reference_options);
      const ident::PeriodicInput reference_input = ForceInput(b, theta, reference_n);
      const ident::PeriodicSolution reference = reference_solver.Solve(reference_input, theta);
      const Eigen::VectorXd reference_stroke = reference.channel("stroke");
      const double range = reference_stroke.maxCoeff() - reference_stroke.minCoeff();
      std::cout << fmt::format(
          "accuracy against cost (stroke error relative to its range, against central4 at n = {}):\n", reference_n);
      std::cout << fmt::format("  {:<10} {:>6} {:>12} {:>10}\n", "scheme", "n", "rel. error", "ms");
      nlohmann::json rows = nlohmann::json::array();
      for (const ident::Scheme scheme :
           {ident::Scheme::kBackward2, ident::Scheme::kCentral2, ident::Scheme::kCentral4, ident::Scheme::kSpectral}) {
        const bool spectral = scheme == ident::Scheme::kSpectral;
        for (int n = spectral ? 32 : 50; n <= (spectral ? 256 : 3200); n *= 2) {
          ident::PeriodicSolverOptions options;
          options.scheme = scheme;
          ident::PeriodicSolver solver(model, options);
          // Same force input, sampled on the coarse grid from the reference grid.
          ident::PeriodicInput input{b.frequency, {}};
          for (int mu = 0; mu < n; ++mu) input.values.push_back(reference_input.values[mu * (reference_n / n)]);
          ident::PeriodicSolution s;
          double ms = 0;
          try {
            ms = MedianMs(quick ? 1 : 3, [&] { s = solver.Solve(input, theta); });
          } catch (const ident::PeriodicSolverError& e) {
            std::cout << fmt::format("  {:<10} {:>6} {:>12}\n", ident::ToString(scheme), n, "no solution");
            continue;
          }
          const Eigen::VectorXd stroke = s.channel("stroke");
          double error = 0.0;
          for (int mu = 0; mu < n; ++mu)
            error = std::max(error, std::abs(stroke[mu] - reference_stroke[mu * (reference_n / n)]));
          std::cout << fmt::format("  {:<10} {:>6} {:>12.3e} {:>10.3f}\n", ident::ToString(scheme), n, error / range, ms);
          rows.push_back({{"scheme", ident::ToString(scheme)}, {"n", n}, {"relative_error", error / range}, {"ms", ms}});
        }
      }
      report["accuracy"] = rows;
    }

    report["time_to_accuracy"] = TimeToAccuracy(b);

    if (!json_path.empty()) {
      std::ofstream out(json_path);
      out << report.dump(1) << "\n";
      if (!out) throw std::runtime_error("cannot write " + json_path);
    }
  }
};

// ---------------------------------------------------------------------------------------------
// strut bench sim: throughput of the simulated rig, the whole standard matrix with settling and
// every effect on (the default truth), then a 30 s drop test. Single-threaded.

struct BenchSim {
  std::string json_path;
  std::string truth_path;

  void Run() const {
    const sim::Truth truth = truth_path.empty() ? sim::DefaultTruth() : sim::ReadTruthFile(truth_path);
    const sim::SimulatedRig rig(truth);
    nlohmann::json report;
    std::cout << fmt::format("simulated rig, {} ({}), standard matrix with settling:\n", rig.model().composition(),
                             truth.source)
              << fmt::format("  {:<4} {:>6} {:>8} {:>10} {:>10} {:>12} {:>9}\n", "exp", "f Hz", "periods", "sim s",
                             "wall ms", "sim s/wall s", "IDA steps");
    std::vector<sim::PeriodicRunReport> reports;
    const auto start = Clock::now();
    rig.RunMatrix(sim::StandardMatrixPlan(), {}, &reports);
    const double wall = std::chrono::duration<double>(Clock::now() - start).count();
    double simulated = 0.0;
    nlohmann::json rows = nlohmann::json::array();
    for (const sim::PeriodicRunReport& r : reports) {
      simulated += r.simulated_seconds;
      const double f = r.periods_simulated / r.simulated_seconds;
      std::cout << fmt::format("  {:<4} {:>6.2f} {:>8} {:>10.1f} {:>10.1f} {:>12.0f} {:>9}\n", r.label, f,
                               r.periods_simulated, r.simulated_seconds, r.wall_seconds * 1e3,
                               r.simulated_seconds / r.wall_seconds, r.ida_steps);
      rows.push_back({{"label", r.label}, {"periods", r.periods_simulated}, {"simulated_s", r.simulated_seconds},
                      {"wall_s", r.wall_seconds}, {"ida_steps", r.ida_steps}});
    }
    std::cout << fmt::format("  matrix: {:.1f} s simulated in {:.2f} s wall = {:.0f} simulated s per wall s   "
                             "target: whole matrix < 10 s ({})\n",
                             simulated, wall, simulated / wall, wall < 10.0 ? "met" : "MISSED");
    report["matrix"] = {{"experiments", rows}, {"simulated_s", simulated}, {"wall_s", wall},
                        {"simulated_per_wall", simulated / wall}, {"target_wall_s", 10.0}};

    sim::DropSpec drop;
    sim::DropRunReport d;
    const auto drop_start = Clock::now();
    rig.RunDropSession(drop, {}, &d);
    const double drop_wall = std::chrono::duration<double>(Clock::now() - drop_start).count();
    std::cout << fmt::format("drop {} kg at {} m/s, {} s at {} Hz: {:.3f} s wall = {:.0f} simulated s per wall s, {} "
                             "IDA steps; gas time constant {:.2f} s (model {:.2f} s)\n",
                             drop.mass, drop.impact_velocity, drop.duration, truth.acquisition.drop_sample_rate,
                             drop_wall, drop.duration / drop_wall, d.ida_steps, d.thermal_time_constant_fit,
                             d.thermal_time_constant_model);
    report["drop"] = {{"simulated_s", drop.duration}, {"wall_s", drop_wall}, {"ida_steps", d.ida_steps},
                      {"time_constant_fit_s", d.thermal_time_constant_fit},
                      {"time_constant_model_s", d.thermal_time_constant_model}};
    if (!json_path.empty()) {
      std::ofstream out(json_path);
      out << report.dump(1) << "\n";
      if (!out) throw std::runtime_error("cannot write " + json_path);
    }
  }
};

}  // namespace

//! strut bench silverbox: the Silverbox benchmark from the raw files (docs/silverbox.md).
struct BenchSilverbox {
  std::string data_dir, json_path, report_path;
  std::vector<std::string> models;
  int refine = 4, substeps = 8, threads = 0;
  bool no_check = false;

  void Run() const {
    const auto start = Clock::now();
    const daq::Session session = ident::ReadSilverbox(data_dir);
    const double import_seconds = std::chrono::duration<double>(Clock::now() - start).count();
    ident::SilverboxOptions options;
    options.models = models.empty() ? ident::SilverboxCandidateModels() : models;
    options.refine = refine;
    options.substeps = substeps;
    options.threads = threads;
    const ident::SilverboxResult r = ident::RunSilverbox(session, options);
    const ident::SilverboxCandidate& best = r.best();

    // Cross-check of the test simulation: IDA (sim::TransientSimulator) on the same model and input.
    nlohmann::json check = nullptr;
    std::vector<std::string> notes;
    if (!no_check) {
      const ident::Model model = ident::Model::Build(best.model, ident::Causality::kForceInput);
      const daq::Experiment& arrow = session.experiment("arrow");
      const std::vector<double>& u = arrow.channel("u").samples;
      constexpr int kFine = 16;
      const double fs = arrow.sample_rate, h = 1.0 / (fs * kFine);
      // The same band-limited input as the RK4 run, evaluated between its fine points by cubic Lagrange.
      const std::vector<double> fine = ident::BandLimitedRecord(u, kFine);
      const sim::InputSignal input([&fine, h](double t) {
        const double p = t / h;
        const long i = static_cast<long>(std::floor(p));
        const double s = p - i;
        const auto at = [&](long j) { return fine[std::clamp<long>(j, 0, static_cast<long>(fine.size()) - 1)]; };
        const double v = -s * (s - 1) * (s - 2) / 6 * at(i - 1) + (s + 1) * (s - 1) * (s - 2) / 2 * at(i) -
                         (s + 1) * s * (s - 2) / 2 * at(i + 1) + (s + 1) * s * (s - 1) / 6 * at(i + 2);
        return sim::InputSample{v, 0.0, 0.0};
      });
      sim::TransientOptions to;
      to.rtol = 1e-8;
      to.atol_factor = 10.0;
      to.max_steps = 20'000'000;
      const sim::TransientSimulator simulator(model, to);
      std::vector<double> times(u.size());
      for (std::size_t i = 0; i < times.size(); ++i) times[i] = i / fs;
      const auto t0 = Clock::now();
      const sim::TransientResult ida = simulator.Simulate(best.fit.parameters.values(), input, times);
      const double ida_seconds = std::chrono::duration<double>(Clock::now() - t0).count();
      const Eigen::VectorXd y = ida.channel("y");
      double max_diff = 0.0, sum = 0.0;
      long count = 0;
      for (std::size_t i = 0; i < times.size(); ++i) max_diff = std::max(max_diff, std::abs(y[i] - r.arrow_simulated[i]));
      for (long i = ident::SilverboxLayout::kTransient; i < static_cast<long>(times.size()); ++i, ++count)
        sum += std::pow(r.arrow_measured[i] - y[i], 2);
      const double ida_rms = 1e3 * std::sqrt(sum / count);
      check = {{"integrator", "IDA (sim::TransientSimulator), rtol 1e-8"},
               {"seconds", ida_seconds},
               {"steps", ida.steps},
               {"max_difference_uv", 1e6 * max_diff},
               {"test_arrow_rms_mv", ida_rms}};
      notes.push_back(fmt::format(
          "Cross-check of the test simulation: SUNDIALS IDA (rtol 1e-8) on the same model and input gives an arrow "
          "RMS of {:.4f} mV; it differs from the RK4 run by at most {:.2f} µV ({} steps, {:.2f} s; RK4 {:.2f} s).",
          ida_rms, 1e6 * max_diff, ida.steps, ida_seconds, r.simulate_seconds));
    }

    std::cout << fmt::format("Silverbox (classic split), model {}\n", best.model);
    std::cout << fmt::format("  candidates (chosen by validation RMS):\n");
    for (const auto& c : r.candidates)
      std::cout << fmt::format("    {:<72} estimation {:.4f} mV  validation {:.4f} mV  BIC {:.1f}\n", c.model,
                               c.estimation_rms_mv, c.validation_rms_mv, c.fit.bic);
    std::cout << fmt::format("  validation RMS (realisation 9)         {:.4f} mV\n", best.validation_rms_mv);
    std::cout << fmt::format("  test RMS, arrow y[486, 40486)           {:.4f} mV\n", r.test_arrow_rms_mv);
    std::cout << fmt::format("  test RMS, no extrapolation y[486, 32100) {:.4f} mV\n", r.test_arrow_no_extrapolation_rms_mv);
    std::cout << fmt::format("  fit of 9 periods                        {:.2f} s wall, {:.2f} s CPU ({} iterations)\n",
                             best.fit_seconds, best.fit_cpu_seconds, best.fit.iterations);
    std::cout << fmt::format("  import {:.2f} s, arrow simulation {:.2f} s\n", import_seconds, r.simulate_seconds);
    for (const auto& n : notes) std::cout << "  " << n << "\n";
    std::cout << "  parameters (95 % intervals):\n";
    for (int i = 0; i < best.fit.parameters.size(); ++i) {
      const auto& spec = best.fit.parameters.spec(i);
      const double v = best.fit.parameters.value(i), sd = best.fit.sd[i];
      std::cout << fmt::format("    {:<8} {:<20} {:>14.7g} +- {:.3g}  [{:.7g}, {:.7g}] {}\n", spec.key(), spec.name, v,
                               1.96 * sd, v - 1.96 * sd, v + 1.96 * sd, spec.unit);
    }
    if (!json_path.empty()) {
      nlohmann::json out = ident::SilverboxToJson(r, options);
      out["import_seconds"] = import_seconds;
      out["data"] = session.source_path;
      out["test_simulation_check"] = check;
      std::ofstream file(json_path);
      file << out.dump(1) << "\n";
      if (!file) throw std::runtime_error("cannot write " + json_path);
      spdlog::info("wrote {}", json_path);
    }
    if (!report_path.empty()) {
      ident::WriteSilverboxReport(r, options, report_path, notes);
      spdlog::info("wrote {}", report_path);
    }
  }
};void RegisterBenchCommand(CLI::App& app) {
  CLI::App* bench = app.add_subcommand("bench", "Benchmarks: figures and ratios measured side by side");
  bench->require_subcommand(1);
  auto periodic = std::make_shared<BenchPeriodic>();
  CLI::App* sub = bench->add_subcommand("periodic", "Periodic solver: cold/warm, growth with n, accuracy vs cost");
  sub->add_option("--json", periodic->json_path, "Also write the figures as JSON");
  sub->add_flag("--quick", periodic->quick, "Fewer repeats (for a smoke run)");
  sub->callback([periodic] { periodic->Run(); });

  auto simulated = std::make_shared<BenchSim>();
  CLI::App* sim_bench = bench->add_subcommand(
      "sim", "Simulated rig: simulated seconds per wall second, standard matrix with settling, every effect on");
  sim_bench->add_option("--json", simulated->json_path, "Also write the figures as JSON");
  sim_bench->add_option("--truth", simulated->truth_path, "Truth file (default: the built-in one)")->check(CLI::ExistingFile);
  sim_bench->callback([simulated] { simulated->Run(); });

  auto silverbox = std::make_shared<BenchSilverbox>();
  CLI::App* sb = bench->add_subcommand(
      "silverbox", "Silverbox benchmark from the raw files: periodic fit, validation, arrow test (classic split)");
  sb->add_option("--data", silverbox->data_dir, "Directory with SNLS80mV.mat (or .csv)")->required()->check(CLI::ExistingDirectory);
  sb->add_option("--json", silverbox->json_path, "Also write the figures as JSON");
  sb->add_option("--report", silverbox->report_path, "Write a self-contained HTML report");
  sb->add_option("--model", silverbox->models,
                 "Candidate composition(s); the lowest validation RMS is tested (default: linear, Duffing, Duffing "
                 "with quadratic stiffness, Duffing with an output offset)");
  sb->add_option("--refine", silverbox->refine, "Periodic-solver grid points per sample")
      ->check(CLI::Range(1, 64))
      ->capture_default_str();
  sb->add_option("--substeps", silverbox->substeps, "RK4 steps per sample in the arrow simulation")
      ->check(CLI::Range(1, 256))
      ->capture_default_str();
  sb->add_option("--threads", silverbox->threads, "Estimator threads (0: one per core)")->capture_default_str();
  sb->add_flag("--no-check", silverbox->no_check, "Skip the IDA cross-check of the arrow simulation");
  sb->callback([silverbox] { silverbox->Run(); });}

}  // namespace strut::tools
