// strut bench: speed and accuracy figures, measured side by side in one run (medians and ratios).
// `bench periodic` measures here; the other benchmarks print and write what the studies
// (strut::study) return.
#include <spdlog/spdlog.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <functional>
#include <iostream>
#include <nlohmann/json.hpp>
#include <time.h>

#include "commands.h"
#include "option_checks.h"
#include "output_files.h"
#include "strut/ident/periodic.h"
#include "strut/rig/test_matrix.h"
#include "strut/sim/periodic_session.h"
#include "strut/sim/simulated_rig.h"
#include "strut/sim/transient.h"
#include "strut/study/cpu_time.h"
#include "strut/study/identify.h"
#include "strut/study/silverbox.h"
#include "strut/study/sim_speed.h"

namespace strut::tools {
namespace {

using Clock = std::chrono::steady_clock;

//! CPU time of the calling thread, ms: unlike wall time it does not count the time other
//! processes of a shared machine take from this one.
double ThreadCpuMs() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return t.tv_sec * 1e3 + t.tv_nsec * 1e-6;
}

//! The q-quantile (0..1) of `times` (reordered); q = 0.5: element size / 2, the median.
double Quantile(std::vector<double>& times, double q) {
  const auto k = static_cast<std::ptrdiff_t>(q * (times.size() - 1) + 0.5);
  std::nth_element(times.begin(), times.begin() + k, times.end());
  return times[k];
}

//! Median CPU time (ms) of the calling thread over `repeats` calls: the solvers are single
//! threaded, so this is their one-core time, without what other processes of a shared machine
//! take from it (wall time there varies by a factor of two from run to run).
double MedianCpuMs(int repeats, const std::function<void()>& run) {
  std::vector<double> times;
  for (int i = 0; i < repeats; ++i) {
    const double start = ThreadCpuMs();
    run();
    times.push_back(ThreadCpuMs() - start);
  }
  return Quantile(times, 0.5);
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
          const double ms = MedianCpuMs(3, [&] { s = solver.Solve(input(n), theta); });
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
        const double ms = MedianCpuMs(1, [&] { r = simulator.PeriodicSteadyState(theta, input(800), steady); });
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

//! One causality's cold and warm solves of experiment b for `bench periodic`: the 2dof model on the
//! grid and scheme a fit under that causality takes by default (force: backward2 on 800 points,
//! fed the stroke-driven solution's force; stroke: central4 on 200, the sine itself).
struct ColdWarmCase {
  const char* name;
  ident::Model model;
  std::vector<double> theta, changed;  // changed: a 1 % change of the estimator's theta4, theta6, theta16
  std::vector<int> estimated;
  ident::PeriodicInput input;
  ident::PeriodicSolver solver;
  ident::PeriodicSolution cold;
  // Warm starts as the estimator has them: the previous solution with its factorisation and, after
  // its sensitivities, its dz/dtheta (the tangent start); then with less.
  std::array<ident::PeriodicSolution, 3> from, result;
  std::vector<double> cold_times;
  std::array<std::vector<double>, 3> warm_times;

  ColdWarmCase(const char* label, ident::Causality causality, const rig::MatrixEntry& b)
      : name(label),
        model(ident::Model::Build("2dof", causality)),
        theta(model.defaults().values()),
        changed(theta),
        input(causality == ident::Causality::kForceInput
                  ? ForceInput(b, theta, ident::DefaultGridPoints(causality))
                  : ident::PeriodicInput::Sine(b.frequency, b.static_position, b.amplitude,
                                               ident::DefaultGridPoints(causality))),
        solver(model, Options(causality)) {
    for (const char* parameter : {"theta4", "theta6", "theta16"}) {
      estimated.push_back(model.defaults().position(parameter));
      changed[estimated.back()] *= 1.01;
    }
  }
  static ident::PeriodicSolverOptions Options(ident::Causality causality) {
    ident::PeriodicSolverOptions options;
    options.scheme = ident::DefaultScheme(causality);
    return options;
  }
  void Cold() {
    const double start = ThreadCpuMs();
    cold = solver.Solve(input, theta);
    cold_times.push_back(ThreadCpuMs() - start);
  }
  void PrepareWarm() {
    from[0] = cold;
    solver.OutputSensitivities(from[0], theta, estimated);  // factorisation at the solution, dz/dtheta
    from[1] = from[0];
    from[1].solver_state.unknown_sensitivities.resize(0, 0);
    from[2] = from[1];
    from[2].solver_state.jacobian.reset();
  }
  void Warm(std::size_t kind) {
    const double start = ThreadCpuMs();
    result[kind] = solver.Solve(input, changed, &from[kind]);
    warm_times[kind].push_back(ThreadCpuMs() - start);
  }
};

//! Section 1 of `bench periodic`: cold and warm solves under force and stroke input in one run, the
//! warm kinds interleaved (one solve of each kind per round, so a change of the machine's load meets
//! all alike). Prints the medians and 10th percentiles side by side; the force-input figures keep
//! their report keys, the stroke-input ones go under "stroke_input".
void ColdAndWarm(const rig::MatrixEntry& b, int repeats, int warm_repeats, nlohmann::json& report) {
  std::array<ColdWarmCase, 2> cases{ColdWarmCase("force input", ident::Causality::kForceInput, b),
                                    ColdWarmCase("stroke input", ident::Causality::kStrokeInput, b)};
  // One causality after the other: solves of the other one in between would evict this one's
  // factorisation and grid from the caches, which no fit does.
  for (ColdWarmCase& c : cases) {
    for (int round = 0; round < repeats; ++round) c.Cold();
    c.PrepareWarm();
    for (int round = 0; round < warm_repeats; ++round)
      for (std::size_t kind = 0; kind < 3; ++kind) c.Warm(kind);
  }
  // The median, and the 10th percentile: the rounds the other processes on a shared core disturbed
  // least (there the median moves by up to 1.4x with their load).
  struct Figure {
    double ms, p10_ms;
  };
  const auto figure = [](std::vector<double> times) { return Figure{Quantile(times, 0.5), Quantile(times, 0.1)}; };
  const auto cell = [](const Figure& f, const ident::PeriodicSolution& s) {
    return fmt::format("{:7.3f} ms (p10 {:.3f}; {} steps, {} fact.)", f.ms, f.p10_ms, s.newton_iterations,
                       s.factorizations);
  };
  std::cout << fmt::format("periodic solve, 2dof, experiment b (CPU time, median of {} cold, {} warm rounds; the "
                           "warm kinds interleaved):\n",
                           repeats, warm_repeats);
  std::cout << fmt::format("  {:<45}", "");
  for (const ColdWarmCase& c : cases)
    std::cout << fmt::format(" {:<44}", fmt::format("{} ({}, n = {})", c.name, ident::ToString(c.solver.options().scheme),
                                                     c.input.values.size()));
  std::cout << "\n";
  const char* names[] = {"warm (estimator: factorisation + dz/dtheta)", "warm (factorisation, no dz/dtheta)",
                         "warm (unknowns only)"};
  std::array<Figure, 2> cold;
  std::array<std::array<Figure, 3>, 2> warm;
  for (std::size_t i = 0; i < cases.size(); ++i) {
    cold[i] = figure(cases[i].cold_times);
    for (std::size_t kind = 0; kind < 3; ++kind) warm[i][kind] = figure(cases[i].warm_times[kind]);
  }
  std::cout << fmt::format("  {:<45}", "cold (coarse-grid start)");
  for (std::size_t i = 0; i < cases.size(); ++i) std::cout << fmt::format(" {:<44}", cell(cold[i], cases[i].cold));
  std::cout << "\n";
  for (std::size_t kind = 0; kind < 3; ++kind) {
    std::cout << fmt::format("  {:<45}", names[kind]);
    for (std::size_t i = 0; i < cases.size(); ++i)
      std::cout << fmt::format(" {:<44}", cell(warm[i][kind], cases[i].result[kind]));
    std::cout << "\n";
  }
  std::cout << fmt::format("  {:<45}", "cold / warm (estimator)");
  for (std::size_t i = 0; i < cases.size(); ++i) std::cout << fmt::format(" {:<44.1f}", cold[i].ms / warm[i][0].ms);
  std::cout << fmt::format("\n  force input targets: cold < 2 ms {}, warm (estimator) < 0.2 ms {}   (1 % change of "
                           "theta4, theta6, theta16)\n",
                           cold[0].ms < 2.0 ? "met" : "MISSED", warm[0][0].ms < 0.2 ? "met" : "MISSED");
  const auto keys = [&](std::size_t i, nlohmann::json& out) {
    out["cold_ms"] = cold[i].ms;
    out["cold_p10_ms"] = cold[i].p10_ms;
    out["cold_iterations"] = cases[i].cold.newton_iterations;
    out["cold_factorizations"] = cases[i].cold.factorizations;
    out["warm_ms"] = warm[i][0].ms;
    out["warm_p10_ms"] = warm[i][0].p10_ms;
    out["warm_iterations"] = cases[i].result[0].newton_iterations;
    out["warm_factorisation_only_ms"] = warm[i][1].ms;
    out["warm_unknowns_only_ms"] = warm[i][2].ms;
  };
  keys(0, report);
  nlohmann::json stroke;
  stroke["scheme"] = ident::ToString(cases[1].solver.options().scheme);
  stroke["n"] = cases[1].input.values.size();
  keys(1, stroke);
  report["stroke_input"] = stroke;
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

    // 1. Cold and warm solves, experiment b, both causalities side by side.
    ColdAndWarm(b, repeats, quick ? 21 : 201, report);

    // 2. Cost growth with n: time per Newton iteration must grow linearly.
    {
      std::cout << "cost growth with n (2dof force-driven, experiment b, from the unknowns of the solution at the same\n"
                   "n after a 1 % change of theta4, a new Jacobian every step):\n"
                << fmt::format("  {:>6} {:>12} {:>16} {:>18}\n", "n", "solve ms", "ms / iteration", "per-point ratio");
      nlohmann::json rows = nlohmann::json::array();
      double base_per_point = 0.0;
      for (int n = 100; n <= 12800; n *= 2) {
        const ident::PeriodicInput input = ForceInput(b, theta, n);
        ident::PeriodicSolverOptions full_newton;
        full_newton.reuse_contraction = 0.0;  // every step a full Newton step: the cost per step is comparable
        ident::PeriodicSolver solver(model, full_newton);
        ident::PeriodicSolution start = solver.Solve(input, theta);
        start.solver_state.jacobian.reset();
        std::vector<double> changed = theta;
        changed[model.defaults().position("theta4")] *= 1.01;
        ident::PeriodicSolution s;
        const double ms = MedianCpuMs(quick ? 3 : 7, [&] { s = solver.Solve(input, changed, &start); });
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
            ms = MedianCpuMs(quick ? 1 : 3, [&] { s = solver.Solve(input, theta); });
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
      WriteJsonOutput(json_path, report);
    }
  }
};

// ---------------------------------------------------------------------------------------------
// strut bench identify: the identification issue's figures (fit time, interval coverage, and the
// same fit with transient integration to steady state instead of the periodic solver), measured by
// the study (study::MeasureFitTimes, MeasureCoverage, CompareWithTransient) and printed here.

nlohmann::json FitJson(const study::TimedFit& t, const ident::ParameterSet& truth) {
  nlohmann::json estimates = nlohmann::json::object();
  for (int i : t.fit.estimated_positions)
    estimates[truth.spec(i).key()] = {{"value", t.fit.parameters.value(i)},
                                      {"sd", t.fit.estimates[i].sd},
                                      {"truth", truth.value(i)},
                                      {"z", (t.fit.parameters.value(i) - truth.value(i)) / t.fit.estimates[i].sd}};
  return {{"ms", t.ms},
          {"cpu_ms", t.cpu_ms},
          {"runs", t.runs},
          {"converged", t.fit.converged},
          {"iterations", t.fit.iterations},
          {"solves", t.tally.solves},
          {"cold_solves", t.tally.cold_solves},
          {"cold_ms", t.tally.cold_ms},
          {"failed_solves", t.tally.failures},
          {"sensitivity_calls", t.tally.sensitivity_calls},
          {"solve_ms", t.tally.solve_ms},
          {"sensitivity_ms", t.tally.sensitivity_ms},
          {"estimates", estimates}};
}

// 1. Full fit of the standard matrix: time against the 50 ms target.
nlohmann::json PrintFitTimes(const std::vector<study::FitTimeRow>& fits, std::size_t experiments, int repeats,
                             const ident::ParameterSet& truth) {
  std::cout << fmt::format(
      "1. full fit: 2dof, {} experiments of the standard matrix, estimating {} (the rest fixed at the truth),\n"
      "   n = {}, backward2, one thread, median of {} fits; target < {:.0f} ms (judged on the CPU time)\n",
      experiments, study::kIdentifyEstimate, study::kIdentifyN, repeats, study::kFitTargetMs);
  std::cout << fmt::format("   {:<7} {:<9} {:>8} {:>8} {:>7} {:>5} {:>7} {:>5} {:>9} {:>8} {:>8} {:>8}  {}\n", "input",
                           "start", "fit ms", "cpu ms", "target", "iter", "solves", "sens", "solve ms", "cold ms",
                           "sens ms", "other ms", "max |estimate - truth| / sd");
  nlohmann::json rows = nlohmann::json::array();
  for (const study::FitTimeRow& f : fits) {
    const study::TimedFit& t = f.timed;
    std::cout << fmt::format("   {:<7} {:<9} {:>8.1f} {:>8.1f} {:>7} {:>5} {:>7} {:>5} {:>9.1f} {:>8.1f} {:>8.1f} {:>8.1f}  {:.2f}{}\n",
                             ident::ToString(f.causality), f.from_truth ? "truth" : "20 % off", t.ms, t.cpu_ms,
                             t.cpu_ms < study::kFitTargetMs ? "met" : "MISSED", t.fit.iterations, t.tally.solves,
                             t.tally.sensitivity_calls, t.tally.solve_ms, t.tally.cold_ms, t.tally.sensitivity_ms,
                             t.ms - t.tally.solve_ms - t.tally.sensitivity_ms, f.worst_z,
                             t.fit.converged ? "" : "  NOT CONVERGED");
    if (t.tally.failures > 0) std::cout << fmt::format("      ({} solves failed)\n", t.tally.failures);
    nlohmann::json row = FitJson(t, truth);
    row["input"] = ident::ToString(f.causality);
    row["start"] = f.from_truth ? "truth" : "20% off";
    row["target_ms"] = study::kFitTargetMs;
    rows.push_back(row);
  }
  std::cout << "   (solve ms: time inside the periodic solves of the last fit, cold ms the part in the first solve of\n"
               "    each experiment (no warm start); sens ms: sensitivity calls; other: the estimator itself)\n";
  return rows;
}

// 2. Calibration of the reported uncertainty.
nlohmann::json PrintCoverage(const study::CoverageStudy& c) {
  const int count = c.realisations;
  std::cout << fmt::format(
      "2. 95 % intervals (estimate +- 1.96 sd) holding the truth: {} noise realisations of the standard matrix\n"
      "   (stroke input, 14 experiments, sensor noise {:.0e} m / {:.0f} N / {:.0f} Pa, 3 periods at 200 Hz, n = {},\n"
      "   estimating {}, started at the truth; {:.0f} s for both schemes)\n",
      count, c.noise.stroke, c.noise.force, c.noise.pressure, study::kIdentifyN, study::kIdentifyEstimate, c.seconds);
  std::cout << fmt::format("   {:<10} {:<16} {:>9} {:>9} {:>18} {:>8} {:>7}\n", "scheme", "parameter", "inside",
                           "fraction", "Wilson 95 % range", "mean z", "sd z");
  nlohmann::json out = {{"realisations", count},
                        {"seconds", c.seconds},
                        {"nominal_range95", {c.nominal_range95.first, c.nominal_range95.second}}};
  for (const study::SchemeCoverage& s : c.schemes) {
    const std::string scheme(ident::ToString(s.scheme));
    nlohmann::json js = {{"not_converged", s.not_converged}};
    bool first = true;
    for (const auto& [key, z] : s.parameters) {
      std::cout << fmt::format("   {:<10} {:<16} {:>4}/{:<4} {:>9.3f}     [{:.3f}, {:.3f}] {:>8.2f} {:>7.2f}\n",
                               first ? scheme : "", key, z.inside, count, z.fraction(), z.wilson95.first,
                               z.wilson95.second, z.mean_z, z.sd_z);
      first = false;
      js["parameters"][key] = {{"inside", z.inside},
                               {"fraction", z.fraction()},
                               {"wilson95", {z.wilson95.first, z.wilson95.second}},
                               {"mean_z", z.mean_z},
                               {"sd_z", z.sd_z}};
    }
    const auto w = study::Wilson(s.pooled_inside, s.pooled_total);
    const double pooled = static_cast<double>(s.pooled_inside) / s.pooled_total;
    std::cout << fmt::format("   {:<10} {:<16} {:>4}/{:<4} {:>9.3f}     [{:.3f}, {:.3f}]   (pooled; intervals of one fit "
                             "are correlated)\n",
                             "", "all three", s.pooled_inside, s.pooled_total, pooled, w.first, w.second);
    const auto wj = study::Wilson(s.jointly_inside, count);
    const double jointly = static_cast<double>(s.jointly_inside) / count;
    std::cout << fmt::format("   {:<10} {:<16} {:>4}/{:<4} {:>9.3f}     [{:.3f}, {:.3f}]   (all three at once){}\n", "",
                             "jointly", s.jointly_inside, count, jointly, wj.first, wj.second,
                             s.not_converged > 0 ? fmt::format("; {} fits not converged", s.not_converged) : "");
    js["overall"] = {{"inside", s.pooled_inside}, {"total", s.pooled_total}, {"fraction", pooled},
                     {"wilson95", {w.first, w.second}}};
    js["jointly"] = {{"inside", s.jointly_inside}, {"fraction", jointly}, {"wilson95", {wj.first, wj.second}}};
    out[scheme] = js;
  }
  std::cout << fmt::format("   a calibrated 95 % interval puts the fraction in [{:.3f}, {:.3f}] with 95 % probability "
                           "(binomial, {} realisations);\n   z = (estimate - truth) / sd should have mean 0 and sd 1\n",
                           c.nominal_range95.first, c.nominal_range95.second, count);
  return out;
}

// 3. The same fit with transient integration to steady state.
nlohmann::json PrintTransient(const study::TransientComparison& c, const ident::ParameterSet& truth) {
  const sim::TransientPredictorOptions& o = c.options;
  const std::string start = c.off == 0.0 ? "truth" : fmt::format("{:.0f} % off", 100 * c.off);
  std::cout << fmt::format(
      "3. the same fit with predictions from transient integration to steady state ({} input, experiments {},\n"
      "   n = {}, start: {}): IDA to periodic steady state (warm-started from the previous one; rtol {:.0e},\n"
      "   atol {:.0e} x unknown scale, steady when the change between periods and its extrapolation are below\n"
      "   {:.0e} of each unknown's peak) and IDAS forward sensitivities (exact dF/dtheta from the model's Jets, steps\n"
      "   by the state's error test) integrated until they are periodic too (relative {:.0e}), for the {} estimated\n"
      "   parameters only. Periodic: median of {}; transient: one fit.\n",
      ident::ToString(c.causality), c.experiments, study::kIdentifyN, start, o.integrator.rtol,
      o.integrator.atol_factor, o.steady.relative_floor * o.steady.tol, o.sensitivity_relative_tol, c.estimated,
      c.repeats);
  nlohmann::json out = {{"input", ident::ToString(c.causality)},
                        {"experiments", c.experiments},
                        {"start", start},
                        {"transient_rtol", o.integrator.rtol},
                        {"transient_atol_factor", o.integrator.atol_factor},
                        {"transient_steady_relative", o.steady.relative_floor * o.steady.tol},
                        {"transient_sensitivity_relative", o.sensitivity_relative_tol}};
  if (!c.transient_error.empty()) {
    std::cout << fmt::format("   the transient fit failed: {}\n", c.transient_error);
    out["transient_error"] = c.transient_error;
    return out;
  }
  // The reference is the most accurate of the three: the periodic solver with central4 (its
  // discretisation error at n = 800 is about 1e-10 of the range, docs/periodic-solver.md).
  std::cout << fmt::format("   {:<20} {:>10} {:>10} {:>5} {:>7} {:>5} {:>10} {:>10}  {}\n", "predictor", "fit ms",
                           "cpu ms", "iter", "solves", "sens", "solve ms", "sens ms",
                           "(estimate - central4's) / posterior sd");
  const study::TimedFit& central = c.central4;
  const auto row = [&](const char* name, const study::TimedFit& t) {
    std::string diff;
    double worst = 0.0;
    for (int i : t.fit.estimated_positions) {
      const double d = (t.fit.parameters.value(i) - central.fit.parameters.value(i)) / central.fit.estimates[i].sd;
      worst = std::max(worst, std::abs(d));
      diff += fmt::format(" {} {:+.4f}", truth.spec(i).key(), d);
    }
    std::cout << fmt::format("   {:<20} {:>10.1f} {:>10.1f} {:>5} {:>7} {:>5} {:>10.1f} {:>10.1f} {}{}\n", name, t.ms,
                             t.cpu_ms, t.fit.iterations, t.tally.solves, t.tally.sensitivity_calls, t.tally.solve_ms,
                             t.tally.sensitivity_ms, diff, t.fit.converged ? "" : "  NOT CONVERGED");
    if (t.tally.failures > 0) std::cout << fmt::format("      ({} solves failed)\n", t.tally.failures);
    nlohmann::json j = FitJson(t, truth);
    j["max_sd_from_central4"] = worst;
    return j;
  };
  const study::TimedFit &backward = c.backward2, &transient = c.transient;
  out["periodic_backward2"] = row("periodic backward2", backward);
  out["periodic_central4"] = row("periodic central4", central);
  out["transient"] = row("transient (IDA/IDAS)", transient);
  const auto& ts = transient.tally.transient;
  out["transient"]["periods"] = ts.solve_periods;
  out["transient"]["ida_steps"] = ts.solve_steps;
  out["transient"]["sensitivity_periods"] = ts.sensitivity_periods;
  out["transient"]["idas_steps"] = ts.sensitivity_steps;
  std::cout << fmt::format(
      "   transient work: {} steady states, {} periods, {} IDA steps; {} sensitivity runs, {} periods, {} IDAS steps\n",
      ts.solves, ts.solve_periods, ts.solve_steps, ts.sensitivity_runs, ts.sensitivity_periods, ts.sensitivity_steps);
  std::cout << fmt::format("   time ratio transient / periodic: {:.0f} wall, {:.0f} CPU (against backward2); {:.0f} wall, "
                           "{:.0f} CPU (against central4)\n",
                           transient.ms / backward.ms, transient.cpu_ms / backward.cpu_ms, transient.ms / central.ms,
                           transient.cpu_ms / central.cpu_ms);
  out["ratio_backward2"] = transient.ms / backward.ms;
  out["ratio_central4"] = transient.ms / central.ms;
  out["cpu_ratio_backward2"] = transient.cpu_ms / backward.cpu_ms;
  out["cpu_ratio_central4"] = transient.cpu_ms / central.cpu_ms;
  return out;
}

struct BenchIdentify {
  std::string json_path;
  bool quick = false;
  int realisations = 0;               // 0: 200 (quick: 20)
  std::string transient_experiments;  // empty: all (quick: "hi")
  bool transient_force = false;       // also the force-input transient fit
  study::TransientSettings transient;
  std::string sections = "123";         // which of the three figures to measure
  double transient_off = 0.1;           // start of the transient comparison: the truth this much off
  double coverage_stroke_noise = -1.0;  // m; < 0: the simulated rig's (a diagnostic: 0 removes input noise)

  void Run() const {
    nlohmann::json report;
    const auto start = Clock::now();
    if (const auto load = study::LoadAverages(); std::isfinite(load[0]) && std::isfinite(load[1])) {
      const std::string one = fmt::format("{:.2f}", load[0]), five = fmt::format("{:.2f}", load[1]);
      std::cout << fmt::format("load average at the start: {} (1 min), {} (5 min); timings are medians, ratios side by side\n\n",
                               one, five);
      report["load_average"] = {one, five};
    }
    const ident::ParameterSet truth = study::IdentifyTruth();
    const daq::Session session =
        sim::SimulatePeriodicSession("2dof", truth.values(), rig::StandardMatrix(), sim::PeriodicSessionOptions{});
    const int repeats = quick ? 3 : 11;
    if (sections.find('1') != std::string::npos) {
      report["fit"] = PrintFitTimes(study::MeasureFitTimes(session, truth, repeats), session.experiments.size(),
                                    repeats, truth);
      std::cout << "\n";
    }
    if (sections.find('2') != std::string::npos) {
      const int count = realisations > 0 ? realisations : (quick ? 20 : 200);
      report["coverage"] = PrintCoverage(study::MeasureCoverage(truth, count, coverage_stroke_noise));
      std::cout << "\n";
    }
    if (sections.find('3') != std::string::npos) {
      const std::string labels = quick && transient_experiments.empty() ? "hi" : transient_experiments;
      const auto compare = [&](ident::Causality causality) {
        return PrintTransient(
            study::CompareWithTransient(session, truth, causality, transient_off, labels, transient, repeats), truth);
      };
      report["transient"].push_back(compare(ident::Causality::kStrokeInput));
      if (transient_force) {
        std::cout << "\n";
        report["transient"].push_back(compare(ident::Causality::kForceInput));
      }
    }
    const double seconds = std::chrono::duration<double>(Clock::now() - start).count();
    std::cout << fmt::format("\nbench identify: {:.0f} s\n", seconds);
    report["seconds"] = seconds;
    if (!json_path.empty()) {
      WriteJsonOutput(json_path, report);
    }
  }
};

// ---------------------------------------------------------------------------------------------
// strut bench sim: throughput of the simulated rig (study::MeasureSimSpeed), the whole standard
// matrix with settling and every effect on (the default truth), then a 30 s drop test.

struct BenchSim {
  std::string json_path;
  std::string truth_path;

  void Run() const {
    const sim::Truth truth = truth_path.empty() ? sim::DefaultTruth() : sim::ReadTruthFile(truth_path);
    const study::SimSpeedStudy s = study::MeasureSimSpeed(truth);
    nlohmann::json report;
    std::cout << fmt::format("simulated rig, {} ({}), standard matrix with settling:\n", s.composition, truth.source)
              << fmt::format("  {:<4} {:>6} {:>8} {:>10} {:>10} {:>12} {:>9}\n", "exp", "f Hz", "periods", "sim s",
                             "wall ms", "sim s/wall s", "IDA steps");
    nlohmann::json rows = nlohmann::json::array();
    for (const sim::PeriodicRunReport& r : s.experiments) {
      const double f = r.periods_simulated / r.simulated_seconds;
      std::cout << fmt::format("  {:<4} {:>6.2f} {:>8} {:>10.1f} {:>10.1f} {:>12.0f} {:>9}\n", r.label, f,
                               r.periods_simulated, r.simulated_seconds, r.wall_seconds * 1e3,
                               r.simulated_seconds / r.wall_seconds, r.ida_steps);
      rows.push_back({{"label", r.label}, {"periods", r.periods_simulated}, {"simulated_s", r.simulated_seconds},
                      {"wall_s", r.wall_seconds}, {"ida_steps", r.ida_steps}});
    }
    const double simulated = s.simulated, wall = s.matrix_wall;
    std::cout << fmt::format("  matrix: {:.1f} s simulated in {:.2f} s wall = {:.0f} simulated s per wall s   "
                             "target: whole matrix < 10 s ({})\n",
                             simulated, wall, simulated / wall, wall < 10.0 ? "met" : "MISSED");
    report["matrix"] = {{"experiments", rows}, {"simulated_s", simulated}, {"wall_s", wall},
                        {"simulated_per_wall", simulated / wall}, {"target_wall_s", 10.0}};
    const sim::DropSpec& drop = s.drop;
    const sim::DropRunReport& d = s.drop_report;
    std::cout << fmt::format("drop {} kg at {} m/s, {} s at {} Hz: {:.3f} s wall = {:.0f} simulated s per wall s, {} "
                             "IDA steps; gas time constant {:.2f} s (model {:.2f} s)\n",
                             drop.mass, drop.impact_velocity, drop.duration, truth.acquisition.drop_sample_rate,
                             s.drop_wall, drop.duration / s.drop_wall, d.ida_steps, d.thermal_time_constant_fit,
                             d.thermal_time_constant_model);
    report["drop"] = {{"simulated_s", drop.duration}, {"wall_s", s.drop_wall}, {"ida_steps", d.ida_steps},
                      {"time_constant_fit_s", d.thermal_time_constant_fit},
                      {"time_constant_model_s", d.thermal_time_constant_model}};
    if (!json_path.empty()) {
      WriteJsonOutput(json_path, report);
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
    const daq::Session session = study::ReadSilverbox(data_dir);
    const double import_seconds = std::chrono::duration<double>(Clock::now() - start).count();
    study::SilverboxOptions options;
    options.models = models.empty() ? study::SilverboxCandidateModels() : models;
    options.refine = refine;
    options.substeps = substeps;
    options.threads = threads;
    const study::SilverboxResult r = study::RunSilverbox(session, options);
    const study::SilverboxCandidate& best = r.best();

    // Cross-check of the test simulation: IDA (sim::TransientSimulator) on the same model and input.
    nlohmann::json check = nullptr;
    std::vector<std::string> notes;
    if (!no_check) {
      const study::SilverboxSimulationCheck c = study::CheckArrowSimulation(session, r);
      check = {{"integrator", "IDA (sim::TransientSimulator), rtol 1e-8"},
               {"seconds", c.seconds},
               {"steps", c.steps},
               {"max_difference_uv", c.max_difference_uv},
               {"test_arrow_rms_mv", c.test_arrow_rms_mv}};
      notes.push_back(fmt::format(
          "Cross-check of the test simulation: SUNDIALS IDA (rtol 1e-8) on the same model and input gives an arrow "
          "RMS of {:.4f} mV; it differs from the RK4 run by at most {:.2f} µV ({} steps, {:.2f} s; RK4 {:.2f} s).",
          c.test_arrow_rms_mv, c.max_difference_uv, c.steps, c.seconds, r.simulate_seconds));
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
      const double v = best.fit.parameters.value(i), sd = best.fit.estimates[i].sd;
      std::cout << fmt::format("    {:<8} {:<20} {:>14.7g} +- {:.3g}  [{:.7g}, {:.7g}] {}\n", spec.key(), spec.name, v,
                               1.96 * sd, v - 1.96 * sd, v + 1.96 * sd, spec.unit);
    }
    if (!json_path.empty()) {
      nlohmann::json out = study::SilverboxToJson(r, options);
      out["import_seconds"] = import_seconds;
      out["data"] = session.source_path;
      out["test_simulation_check"] = check;
      WriteJsonOutput(json_path, out);
    }
    if (!report_path.empty()) {
      study::WriteSilverboxReport(r, options, report_path, notes);
      spdlog::info("wrote {}", report_path);
    }
  }
};

void RegisterBenchCommand(CLI::App& app) {
  CLI::App* bench = app.add_subcommand("bench", "Run a benchmark: figures and ratios measured side by side, printed (and with --json written as JSON).");
  bench->require_subcommand(1);
  auto [sub, periodic] = AddCommand<BenchPeriodic>(
      *bench, "periodic", "Time the periodic solver: cold and warm solves, growth with n, accuracy against cost.");
  sub->add_option("--json", periodic->json_path, "Also write the figures as JSON to this file.");
  sub->add_flag("--quick", periodic->quick, "Run fewer repeats (a smoke run).");

  auto [id, identify] = AddCommand<BenchIdentify>(*bench, "identify",
                                                  "Measure the estimator: fit time on the standard matrix, interval "
                                                  "coverage, periodic against transient predictions.");
  id->add_option("--json", identify->json_path, "Also write the figures as JSON to this file.");
  id->add_flag("--quick", identify->quick, "Run fewer repeats and realisations and a two-experiment transient fit (a smoke run).");
  id->add_option("--realisations", identify->realisations, "Noise realisations for the coverage (default 200; with --quick 20).")
      ->check(Between(2, 100000));
  id->add_option("--transient-experiments", identify->transient_experiments,
                 "The labels of the experiments in the transient comparison, e.g. dehij (default: all; with --quick: hi).");
  id->add_option("--sections", identify->sections, "Which figures to measure: 1 fit time, 2 coverage, 3 transient; e.g. 13 for the first and third.")
      ->capture_default_str();
  id->add_flag("--transient-force", identify->transient_force, "Also compare with force input (slow).");
  id->add_option("--coverage-stroke-noise", identify->coverage_stroke_noise,
                 "The stroke sensor's noise in m in the coverage realisations (default: the simulated rig's; 0: an exact input).")
      ->check(NonNegative("m"));
  id->add_option("--transient-start", identify->transient_off,
                 "The start of the transient comparison: the estimated parameters this fraction too large (0: the truth).")
      ->check(NonNegative())
      ->capture_default_str();
  id->add_option("--transient-rtol", identify->transient.rtol, "The IDA/IDAS relative tolerance of the transient fit.")
      ->check(Positive())
      ->capture_default_str();
  id->add_option("--transient-atol", identify->transient.atol,
                 "The IDA/IDAS absolute tolerances as a multiple of each unknown's scale.")
      ->check(Positive())
      ->capture_default_str();
  id->add_option("--transient-steady", identify->transient.steady,
                 "The transient is steady when the change between periods (extrapolated) is below this fraction of each unknown's peak.")
      ->check(Positive())
      ->capture_default_str();
  id->add_option("--transient-sensitivity", identify->transient.sensitivity,
                 "The sensitivities are periodic when their change is below this fraction of their peak.")
      ->check(Positive())
      ->capture_default_str();

  auto [sim_bench, simulated] = AddCommand<BenchSim>(*bench, "sim",
                                                     "Time the simulated rig: simulated seconds per wall second on the "
                                                     "standard matrix with settling, every effect on.");
  sim_bench->add_option("--json", simulated->json_path, "Also write the figures as JSON to this file.");
  sim_bench->add_option("--truth", simulated->truth_path, "Read the truth from this TOML file (default: the built-in one).")->check(CLI::ExistingFile);

  auto [sb, silverbox] = AddCommand<BenchSilverbox>(*bench, "silverbox",
                                                    "Run the Silverbox benchmark from its raw files: periodic fit, "
                                                    "validation, arrow test (classic split; docs/silverbox.md).");
  sb->add_option("--data", silverbox->data_dir, "The directory holding SNLS80mV.mat (or SNLS80mV.csv).")->required()->check(CLI::ExistingDirectory);
  sb->add_option("--json", silverbox->json_path, "Also write the figures as JSON to this file.");
  sb->add_option("--report", silverbox->report_path, "Write a self-contained HTML report to this file.");
  sb->add_option("--model", silverbox->models,
                 "Candidate composition(s); the lowest validation RMS is tested (default: linear, Duffing, Duffing "
                 "with quadratic stiffness, Duffing with an output offset).");
  sb->add_option("--refine", silverbox->refine, "Periodic-solver grid points per sample.")
      ->check(Between(1, 64))
      ->capture_default_str();
  sb->add_option("--substeps", silverbox->substeps, "RK4 steps per sample in the arrow simulation.")
      ->check(Between(1, 256))
      ->capture_default_str();
  sb->add_option("--threads", silverbox->threads, "Estimator threads (0: one per core).")->check(Between(0, 256))->capture_default_str();
  sb->add_flag("--no-check", silverbox->no_check, "Skip the IDA cross-check of the arrow simulation.");

  RegisterBenchAcquisition(*bench);
  RegisterBenchRecorder(*bench);
}

}  // namespace strut::tools
