// strut bench confusion: discovery on drawn units (sim::DrawUnit) that hold one catalogue effect at a
// drawn size, or none: how often the right term is named first, what else is added, and how often
// a unit with nothing missing gets a term anyway (false discoveries).
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <iostream>
#include <map>
#include <optional>
#include <nlohmann/json.hpp>
#include <cmath>
#include <random>
#include <sstream>

#include "commands.h"
#include "option_checks.h"
#include "output_files.h"
#include "strut/ident/discover.h"
#include "strut/sim/draw.h"
#include "strut/sim/simulated_rig.h"

namespace strut::tools {
namespace {

//! The detection study's sizes (--sizes study): per effect the parameter that sets how strongly the
//! unit shows it, drawn from barely detectable to plain (docs/discovery.md, "Detection sizes").
struct StudyRange {
  std::string effect;
  int index;        //!< theta index of the size
  double low, high;
  bool log;         //!< log-uniform (else uniform)
  bool via_draw;    //!< the draw itself spreads it (sim::DrawSpreads); no size is requested
  const char* unit;
};
const std::vector<StudyRange>& StudyRanges() {
  static const std::vector<StudyRange> ranges = {
      {"viscous-damping", 18, 30.0, 3000.0, true, false, "N s/m"},
      {"stribeck-friction", 19, 0.02, 0.6, false, false, "-"},
      {"oil-compressibility", 26, 1e-10, 2e-9, true, false, "1/Pa"},
      {"real-gas", 31, 0.05, 1.5, false, false, "-"},
      {"end-stop", 23, 0.0, 8e-3, false, true, "m"},
  };
  return ranges;
}
const StudyRange* FindStudyRange(const std::string& effect) {
  for (const StudyRange& r : StudyRanges())
    if (r.effect == effect) return &r;
  return nullptr;
}

//! The smallest size (or signal) above which at least 95 % of the units (and at least 10) had the
//! right first term; NaN when no such size.
double DetectionSize(std::vector<std::pair<double, bool>> units) {
  std::sort(units.begin(), units.end());
  for (std::size_t k = 0; k + 10 <= units.size(); ++k) {
    const long right = std::count_if(units.begin() + k, units.end(), [](const auto& u) { return u.second; });
    if (right >= 0.95 * static_cast<double>(units.size() - k)) return units[k].first;
  }
  return NAN;
}

//! The units sorted by their measure in five bins, each with its count of right first terms.
std::string Bins(std::vector<std::pair<double, bool>> units, std::string_view unit) {
  std::sort(units.begin(), units.end());
  std::string bins;
  const std::size_t count = units.size();
  for (std::size_t b = 0; b < 5 && count > 0; ++b) {
    const std::size_t lo = b * count / 5, hi = (b + 1) * count / 5;
    if (hi <= lo) continue;
    const long k = std::count_if(units.begin() + lo, units.begin() + hi, [](const auto& x) { return x.second; });
    bins += fmt::format("    {:.3g}..{:.3g} {}: right first {}/{}\n", units[lo].first, units[hi - 1].first, unit, k,
                        hi - lo);
  }
  return bins;
}

struct BenchConfusion {
  int units = 10;
  unsigned long first_seed = 2000;
  std::string base = "2dof";
  std::string effects = "none,viscous-damping,stribeck-friction,oil-compressibility,real-gas,end-stop";
  bool servo = false;
  std::string sizes = "drawn";
  std::string json_path;
  std::string sessions_dir;

  void Run() const {
    CheckOutputPath("--json", json_path, {});
    sim::Truth around = sim::WithIdealRig(sim::DefaultTruth());
    if (servo) around.actuator.ideal = false;
    ident::SessionFitOptions fit;
    fit.composition = base;
    const ident::Model model = ident::Model::Build(base, fit.causality);
    std::vector<std::string> list;
    std::stringstream in(effects);
    for (std::string item; std::getline(in, item, ',');) list.push_back(item);
    std::cout << fmt::format("discovery from {} on drawn units ({} per row, seeds {}..), {} actuator, perfect calibration:\n",
                             base, units, first_seed, servo ? "servo" : "ideal");
    std::cout << fmt::format("  {:<20} {:>6} {:>12} {:>12} {:>10} {:>10}  {}\n", "truth holds", "units", "right first",
                             "extra terms", "none found", "median s", "what was added");
    nlohmann::json rows = nlohmann::json::array(), unit_rows = nlohmann::json::array();
    std::vector<std::string> detection_lines;
    for (const std::string& effect : list) {
      const StudyRange* study = sizes == "study" ? FindStudyRange(effect) : nullptr;
      if (sizes == "study" && effect != "none" && !study)
        throw std::invalid_argument(fmt::format("--effects: no study range for '{}'", effect));
      int right = 0, extra = 0, none = 0;
      std::vector<double> seconds;
      std::map<std::string, int> added;
      std::vector<std::pair<double, bool>> by_size;    // (size, right first term)
      std::vector<std::pair<double, bool>> by_signal;  // (signal in noise sd, right first term)
      std::vector<std::pair<double, bool>> by_left;    // (signal the baseline leaves, right first term)
      for (int u = 0; u < units; ++u) {
        const unsigned long seed = first_seed + u;
        sim::UnitDraw draw;
        draw.base = base;
        if (effect != "none") {
          std::optional<double> size;
          if (study && !study->via_draw) {
            // Its own stream, so the size does not move the unit's other drawn quantities.
            std::mt19937_64 engine(seed * 7919 + 17);
            const double v = sim::UnitUniform(engine());
            size = study->log ? study->low * std::pow(study->high / study->low, v) : study->low + (study->high - study->low) * v;
          }
          draw.effects.push_back({effect, size});
        }
        const sim::Truth truth = sim::DrawUnit(around, draw, seed);
        // How plainly the effect shows in this unit's data, before any fit absorbs part of it.
        std::optional<sim::EffectSignal> signal;
        if (effect != "none") signal = sim::MeasureEffectSignal(truth, effect, rig::StandardMatrixPlan().experiments);
        const sim::SimulatedRig rig(truth);
        sim::RigRunOptions run;
        run.seed = seed;
        const daq::Session session = rig.RunMatrix(rig::StandardMatrixPlan(), run);
        if (!sessions_dir.empty()) {
          // Kept so that a unit can be looked at again: strut -v discover DIR/EFFECT-SEED.h5 --model BASE.
          const std::string path = fmt::format("{}/{}-{}.h5", sessions_dir, effect, seed);
          CheckOutputPath("--sessions", path, {});
          daq::WriteSession(path, session);
        }
        const auto start = std::chrono::steady_clock::now();
        const ident::DiscoveryResult r =
            ident::Discover(ident::PrepareFitData(session, fmt::format("unit {}", seed), model, fit.estimator.n), fit, {});
        seconds.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
        const bool right_first = effect != "none" && !r.missing.empty() && r.missing.front() == effect;
        if (r.missing.empty()) ++none;
        if (right_first) ++right;
        const std::size_t expected = effect == "none" ? 0 : 1;
        if (r.missing.size() > expected || (effect != "none" && !r.missing.empty() && r.missing.front() != effect)) ++extra;
        std::string names;
        for (const auto& t : r.missing) names += (names.empty() ? "" : "+") + t;
        ++added[names.empty() ? "(nothing)" : names];
        // Per unit: the effect's size and its candidate's first-round scores.
        nlohmann::json row{{"effect", effect}, {"seed", seed}, {"found", r.missing}, {"right_first", right_first},
                           {"seconds", seconds.back()}};
        if (signal) {
          row["signal"] = {{"rms", signal->rms},
                           {"experiment", signal->experiment},
                           {"channel", signal->channel},
                           {"chi2", signal->chi2},
                           {"left_rms", signal->left_rms},
                           {"left_experiment", signal->left_experiment},
                           {"left_channel", signal->left_channel}};
          by_signal.emplace_back(signal->rms, right_first);
          by_left.emplace_back(signal->left_rms, right_first);
        }
        if (study) {
          const ident::ParameterSet p = truth.Parameters(rig.model());
          const double size = p.value(p.position_of_index(study->index));
          row["size"] = size;
          by_size.emplace_back(size, right_first);
        }
        if (!r.steps.empty())
          for (const ident::CandidateFit& c : r.steps.front().candidates)
            if (c.term == effect)
              row["first_round"] = {{"delta_bic", c.delta_bic}, {"cv_ratio", c.cv_ratio}, {"verdict", c.verdict}};
        // A line per unit as it ends, so a long study that is stopped keeps what it measured.
        std::cout << "unit " << row.dump() << std::endl;
        unit_rows.push_back(row);
      }
      // The detection size in the data (the effect's signal) and, in the study, in its parameter.
      const double detection_signal = DetectionSize(by_signal), detection_left = DetectionSize(by_left);
      const double detection_size = study ? DetectionSize(by_size) : NAN;
      const auto shown = [](double x, std::string_view unit) {
        return std::isfinite(x) ? fmt::format("{:.3g} {}", x, unit) : std::string("not reached");
      };
      if (effect != "none") {
        std::string line = fmt::format("  {}: detection (>= 95 % right first above it) in the signal {}, in the signal "
                                       "left after the baseline {}",
                                       effect, shown(detection_signal, "sd"), shown(detection_left, "sd"));
        if (study)
          line += fmt::format(", in theta{} ({} {:.3g}..{:.3g} {}) {}", study->index,
                              study->log ? "log-uniform" : "uniform", study->low, study->high, study->unit,
                              shown(detection_size, study->unit));
        detection_lines.push_back(line + "\n" + Bins(by_signal, "sd"));
      }
      std::sort(seconds.begin(), seconds.end());
      std::string what;
      for (const auto& [names, count] : added) what += fmt::format("{}{} x{}", what.empty() ? "" : ", ", names, count);
      std::cout << fmt::format("  {:<20} {:>6} {:>12} {:>12} {:>10} {:>10.2f}  {}\n", effect, units,
                               effect == "none" ? std::string("-") : std::to_string(right), extra, none,
                               seconds[seconds.size() / 2], what);
      nlohmann::json row{{"effect", effect}, {"units", units}, {"right_first", right}, {"extra", extra},
                         {"nothing_found", none}, {"median_seconds", seconds[seconds.size() / 2]}, {"added", added}};
      if (std::isfinite(detection_signal)) row["detection_signal"] = detection_signal;
      if (std::isfinite(detection_left)) row["detection_left"] = detection_left;
      if (std::isfinite(detection_size)) row["detection_size"] = detection_size;
      rows.push_back(row);
    }
    if (!detection_lines.empty()) {
      std::cout << "detection (signal: the effect's largest RMS over the noise sd in one experiment and channel; "
                   "left: what the baseline's linearised refit leaves of it; units sorted by the signal in five bins):\n";
      for (const std::string& line : detection_lines) std::cout << line;
    }
    if (!json_path.empty())
      WriteTextOutput(json_path, nlohmann::json{{"confusion", rows}, {"sizes", sizes}, {"units", unit_rows}}.dump(1) + "\n");
  }
};

}  // namespace

void RegisterBenchConfusion(CLI::App& bench) {
  auto command = std::make_shared<BenchConfusion>();
  CLI::App* sub = bench.add_subcommand(
      "confusion", "Discovery on drawn units with one catalogue effect or none: right first terms, extras, false discoveries.");
  sub->add_option("--units", command->units, "Drawn units per effect.")->check(Between(1, 10000))->capture_default_str();
  sub->add_option("--first-seed", command->first_seed, "Seed of the first unit.")->capture_default_str();
  sub->add_option("--base", command->base, "The units' base physics and the baseline model: 1dof, 1dof+heat-exchange or 2dof.")
      ->check(CLI::IsMember({"1dof", "1dof+heat-exchange", "2dof"}))
      ->capture_default_str();
  sub->add_option("--effects", command->effects, "The effects, separated by commas; 'none' stands for units with nothing missing.")
      ->capture_default_str();
  sub->add_flag("--servo", command->servo, "Drive the damper through the servo actuator (default: an ideal actuator).");
  sub->add_option("--sizes", command->sizes,
                  "How the effects' sizes are drawn: 'drawn' (the simulated rig's realistic spreads) or 'study' (from "
                  "barely detectable to plain, docs/discovery.md), which also prints the detection size.")
      ->check(CLI::IsMember({"drawn", "study"}))
      ->capture_default_str();
  sub->add_option("--json", command->json_path, "Also write the table and every unit's result as JSON to this file.");
  sub->add_option("--sessions", command->sessions_dir,
                  "Also write every unit's session to this existing folder as EFFECT-SEED.h5 (an existing session is "
                  "refused), to run strut discover on it again.")
      ->check(CLI::ExistingDirectory);
  sub->callback([command] { command->Run(); });
}

}  // namespace strut::tools
