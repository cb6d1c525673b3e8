#include "strut/sim/truth.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <fmt/format.h>
#include <fmt/ranges.h>
#include <map>
#include <set>
#include <string_view>
#include <type_traits>
#include <variant>
#include <vector>

#include "strut/daq/toml_reader.h"

namespace strut::sim {
namespace {

//! Reads one truth file; every message starts with "FILE:LINE:".
class Reader {
 public:
  explicit Reader(std::string source) : source_(source), toml_(std::move(source)) {}

  Truth Read(std::string_view text) {
    const toml::table root = toml_.Parse(text);
    Truth truth;
    truth.source = source_;
    for (auto&& [key, node] : root) {
      const std::string name(key.str());
      if (name == "damper") {
        ReadDamper(Table(node, name), truth);
      } else if (name == "effects") {
        ReadEffects(Table(node, name), truth);
      } else if (name == "parameters") {
        ReadParameters(Table(node, name), truth);
      } else if (name == "actuator") {
        ReadActuator(Table(node, name), truth.actuator);
      } else if (name == "sensors") {
        ReadSensors(Table(node, name), truth.sensors);
      } else if (name == "acquisition") {
        ReadAcquisition(Table(node, name), truth.acquisition);
      } else if (name == "faults") {
        ReadFaults(node, truth.faults);
      } else if (name == "top_out") {
        ReadKeys(Table(node, name), "[top_out] ",
                 {{"stiffness", &truth.top_out.stiffness}, {"dissipation", &truth.top_out.dissipation}});
      } else {
        throw TruthError(fmt::format("{}: unknown table [{}] (known: damper, effects, parameters, actuator, sensors, "
                                     "acquisition, faults, top_out)",
                                     Where(node), name));
      }
    }
    CheckParameters(truth);
    truth.Validate();
    return truth;
  }

 private:
  std::string Where(const toml::node& node) const { return toml_.Where(node); }
  static std::string In(std::string_view section) { return daq::TomlReader<TruthError>::In(section); }
  const toml::table& Table(const toml::node& node, std::string_view name) const { return toml_.Table(node, "", name); }

  // A key of a section and the field its value goes to, read as the field's type.
  struct Key {
    const char* name;
    std::variant<std::string*, double*, long*, int*, bool*> field;
  };

  // Reads every key of `t` into its field, in the file's order; a key not among `keys` is refused
  // naming the ones that are.
  void ReadKeys(const toml::table& t, std::string_view where, std::initializer_list<Key> keys) const {
    for (auto&& [k, node] : t) {
      const std::string key(k.str());
      const Key* known = std::find_if(keys.begin(), keys.end(), [&](const Key& x) { return key == x.name; });
      if (known == keys.end()) {
        std::vector<std::string_view> names;
        for (const Key& x : keys) names.push_back(x.name);
        toml_.UnknownKey(node, where, key, fmt::format("{}", fmt::join(names, ", ")));
      }
      std::visit(
          [&](auto* field) {
            using T = std::remove_pointer_t<decltype(field)>;
            if constexpr (std::is_same_v<T, std::string>) *field = toml_.Text(node, where, key);
            if constexpr (std::is_same_v<T, double>) *field = toml_.Number(node, where, key);
            if constexpr (std::is_same_v<T, long>) *field = toml_.Integer(node, where, key);
            if constexpr (std::is_same_v<T, int>) *field = static_cast<int>(toml_.Integer(node, where, key));
            if constexpr (std::is_same_v<T, bool>) *field = toml_.Bool(node, where, key);
          },
          known->field);
    }
  }

  void ReadDamper(const toml::table& t, Truth& truth) const {
    ReadKeys(t, "[damper] ", {{"serial", &truth.damper_serial}, {"rig", &truth.rig}});
  }

  void ReadEffects(const toml::table& t, Truth& truth) {
    std::set<std::string> on;
    for (auto&& [k, node] : t) {
      const std::string key(k.str());
      const auto& names = Truth::EffectNames();
      if (std::find(names.begin(), names.end(), key) == names.end()) {
        std::string known;
        for (const auto& n : names) known += (known.empty() ? "" : ", ") + n;
        throw TruthError(fmt::format("{}: [effects] unknown effect '{}' (known: {})", Where(node), key, known));
      }
      if (toml_.Bool(node, "[effects] ", key)) on.insert(key);
      effect_lines_[key] = static_cast<int>(node.source().begin.line);
    }
    truth.effects.clear();
    for (const auto& n : Truth::EffectNames())
      if (on.count(n)) truth.effects.push_back(n);
  }

  void ReadParameters(const toml::table& t, Truth& truth) {
    for (auto&& [k, node] : t) {
      const std::string key(k.str());
      if (key == "theta39" || key == "load_cell_zero")
        throw TruthError(fmt::format("{}: [parameters] {}: the load cell's zero is a sensor's, set it as "
                                     "[sensors.force] offset",
                                     Where(node), key));
      truth.parameters.emplace_back(key, toml_.Number(node, "[parameters] ", key));
      parameter_lines_.push_back(static_cast<int>(node.source().begin.line));
    }
  }

  void ReadActuator(const toml::table& t, ActuatorOptions& a) const {
    ReadKeys(t, "[actuator] ",
             {{"ideal", &a.ideal},
              {"loop_bandwidth", &a.loop_bandwidth},
              {"feedforward", &a.feedforward},
              {"valve_bandwidth", &a.valve_bandwidth},
              {"max_velocity", &a.max_velocity},
              {"stall_force", &a.stall_force},
              {"force_limit", &a.force_limit},
              {"control_rate", &a.control_rate}});
  }

  void ReadSensor(const toml::table& t, const std::string& section, SensorOptions& s) const {
    for (auto&& [k, node] : t) {
      const std::string key(k.str());
      if (key == "range") {
        const toml::array* a = node.as_array();
        if (!a || a->size() != 2)
          throw TruthError(fmt::format("{}: [{}] range: expected [low, high]", Where(node), section));
        s.range_min = toml_.Number((*a)[0], In(section), "range");
        s.range_max = toml_.Number((*a)[1], In(section), "range");
      } else if (key == "noise") {
        s.noise = toml_.Number(node, In(section), key);
      } else if (key == "offset") {
        s.offset = toml_.Number(node, In(section), key);
      } else if (key == "gain_error") {
        s.gain_error = toml_.Number(node, In(section), key);
      } else if (key == "bits") {
        s.bits = static_cast<int>(toml_.Integer(node, In(section), key));
      } else {
        toml_.UnknownKey(node, In(section), key, "range, noise, offset, gain_error, bits");
      }
    }
    std::string error;
    if (!s.IsValid(&error)) throw TruthError(fmt::format("{}: [{}] {}", Where(t), section, error));
  }

  void ReadSensors(const toml::table& t, SensorSet& sensors) const {
    for (auto&& [k, node] : t) {
      const std::string key(k.str());
      const std::string section = "sensors." + key;
      if (key == "stroke")
        ReadSensor(Table(node, section), section, sensors.stroke);
      else if (key == "force")
        ReadSensor(Table(node, section), section, sensors.force);
      else if (key == "pressure")
        ReadSensor(Table(node, section), section, sensors.pressure);
      else
        toml_.UnknownKey(node, "[sensors] ", key, "stroke, force, pressure");
    }
  }

  void ReadAcquisition(const toml::table& t, AcquisitionOptions& a) const {
    ReadKeys(t, "[acquisition] ",
             {{"sample_rate", &a.sample_rate},
              {"drop_sample_rate", &a.drop_sample_rate},
              {"periods", &a.periods},
              {"settle_tolerance", &a.settle_tolerance},
              {"settle_periods_max", &a.settle_periods_max},
              {"gauge_pressure", &a.gauge_pressure},
              {"rtol", &a.rtol}});
    std::string error;
    if (!a.IsValid(&error)) throw TruthError(fmt::format("{}: [acquisition] {}", Where(t), error));
  }

  void ReadFaults(const toml::node& node, std::vector<FaultSpec>& faults) const {
    const toml::array* list = node.as_array();
    if (!list) throw TruthError(fmt::format("{}: faults must be an array of tables ([[faults]])", Where(node)));
    for (const toml::node& item : *list) {
      const toml::table* t = item.as_table();
      if (!t) throw TruthError(fmt::format("{}: each fault must be a table ([[faults]])", Where(item)));
      FaultSpec f;
      bool has_kind = false;
      for (auto&& [k, v] : *t) {
        const std::string key(k.str());
        if (key == "experiment") {
          f.experiment = toml_.Text(v, "[faults] ", key);
        } else if (key == "channel") {
          f.channel = toml_.Text(v, "[faults] ", key);
        } else if (key == "kind") {
          try {
            f.kind = ParseFaultKind(toml_.Text(v, "[faults] ", key));
          } catch (const std::invalid_argument& e) {
            throw TruthError(fmt::format("{}: [[faults]] {}", Where(v), e.what()));
          }
          has_kind = true;
        } else if (key == "start") {
          f.start = toml_.Number(v, "[faults] ", key);
        } else if (key == "duration") {
          f.duration = toml_.Number(v, "[faults] ", key);
        } else if (key == "rate") {
          f.rate = toml_.Number(v, "[faults] ", key);
        } else if (key == "amplitude") {
          f.amplitude = toml_.Number(v, "[faults] ", key);
        } else {
          toml_.UnknownKey(v, "[faults] ", key, "experiment, channel, kind, start, duration, rate, amplitude");
        }
      }
      if (!has_kind) throw TruthError(fmt::format("{}: [[faults]] needs a kind", Where(item)));
      std::string error;
      if (!f.IsValid(&error)) throw TruthError(fmt::format("{}: [[faults]] {}", Where(item), error));
      faults.push_back(f);
    }
  }

  // Every parameter name must exist in some model the effects can build; names of effects that
  // are off are ignored with a warning.
  void CheckParameters(const Truth& truth) const {
    if (truth.has_effect("gas-solubility") && !truth.has_effect("heat-exchange")) {
      const auto line = effect_lines_.find("gas-solubility");
      throw TruthError(fmt::format("{}:{}: [effects] gas-solubility needs heat-exchange (the paper's solubility is "
                                   "written with the gas temperature)",
                                   source_, line != effect_lines_.end() ? line->second : 1));
    }
    ident::Model model = [&] {
      try {
        return truth.BuildModel(ident::Causality::kStrokeInput);
      } catch (const ident::ModelError& e) {
        const auto line = effect_lines_.find("gas-solubility");
        throw TruthError(fmt::format("{}:{}: [effects] {}", source_, line != effect_lines_.end() ? line->second : 1,
                                     e.what()));
      }
    }();
    std::vector<ident::ParameterSet> all;
    for (const char* base : {"1dof", "2dof"}) {
      std::string composition = base;
      for (const auto& e : Truth::EffectNames()) {
        if (e == "heat-exchange" || e == "gas-solubility") continue;
        try {  // an effect that needs the gas temperature does not compose with 1dof
          ident::Model::Build(composition + "+" + e, ident::Causality::kStrokeInput);
          composition += "+" + e;
        } catch (const ident::ModelError&) {
        }
      }
      all.push_back(ident::Model::Build(composition, ident::Causality::kStrokeInput).defaults());
    }
    for (std::size_t i = 0; i < truth.parameters.size(); ++i) {
      const auto& [key, value] = truth.parameters[i];
      const int line = parameter_lines_.at(i);
      const auto position = model.defaults().find(key);
      if (!position) {
        const bool known = std::any_of(all.begin(), all.end(), [&](const ident::ParameterSet& s) {
          return s.find(key).has_value();
        });
        if (!known)
          throw TruthError(fmt::format("{}:{}: [parameters] unknown parameter '{}'; the model {} has:\n{}", source_,
                                       line, key, model.composition(), model.defaults().table()));
        spdlog::warn("{}:{}: parameter '{}' is not used by the model {} (its effect is off)", source_, line, key,
                     model.composition());
        continue;
      }
      const ident::ParameterSpec& spec = model.defaults().spec(*position);
      if (!spec.range.contains(value))
        throw TruthError(fmt::format("{}:{}: [parameters] {} = {} is outside its physical range {}", source_, line,
                                     key, value, spec.range.ToString()));
    }
  }

  std::string source_;
  daq::TomlReader<TruthError> toml_;
  std::map<std::string, int> effect_lines_;
  std::vector<int> parameter_lines_;
};

}  // namespace

bool AcquisitionOptions::IsValid(std::string* error) const {
  const auto fail = [&](const std::string& m) {
    if (error) *error = m;
    return false;
  };
  if (!std::isfinite(sample_rate) || !(sample_rate > 0))
    return fail(fmt::format("sample_rate must be positive, got {}", sample_rate));
  if (!std::isfinite(drop_sample_rate) || !(drop_sample_rate > 0))
    return fail(fmt::format("drop_sample_rate must be positive, got {}", drop_sample_rate));
  if (periods < 1 || periods > 1000) return fail(fmt::format("periods must be 1..1000, got {}", periods));
  if (!std::isfinite(settle_tolerance) || !(settle_tolerance > 0))
    return fail(fmt::format("settle_tolerance must be positive, got {}", settle_tolerance));
  if (settle_periods_max < 2) return fail(fmt::format("settle_periods_max must be at least 2, got {}", settle_periods_max));
  if (!std::isfinite(rtol) || rtol < 1e-12 || rtol > 1e-3)
    return fail(fmt::format("rtol must be between 1e-12 and 1e-3, got {}", rtol));
  return true;
}

const std::vector<std::string>& Truth::EffectNames() {
  // In the catalogue's (evaluation) order.
  static const std::vector<std::string> names = {"heat-exchange",      "gas-solubility",        "viscous-damping",
                                                 "stribeck-friction",  "end-stop",              "oil-compressibility",
                                                 "dead-volume",        "charge-loss",           "real-gas",
                                                 "recoil-damping",
                                                 "metering-pin",       "friction-asymmetry",    "pressure-heat-transfer"};
  return names;
}

bool Truth::has_effect(std::string_view name) const {
  return std::find(effects.begin(), effects.end(), name) != effects.end();
}

std::string Truth::Composition() const {
  std::string c = has_effect("heat-exchange") ? (has_effect("gas-solubility") ? "2dof" : "1dof+heat-exchange") : "1dof";
  if (!has_effect("heat-exchange") && has_effect("gas-solubility")) c += "+gas-solubility";  // refused by Build
  for (const auto& e : EffectNames())
    if (e != "heat-exchange" && e != "gas-solubility" && has_effect(e)) c += "+" + e;
  return c;
}

ident::Model Truth::BuildModel(ident::Causality causality) const { return ident::Model::Build(Composition(), causality); }

ident::ParameterSet Truth::Parameters(const ident::Model& model) const {
  ident::ParameterSet p = model.defaults();
  for (const auto& [key, value] : parameters)
    if (p.find(key)) p.set(key, value);
  return p;
}

ident::ParameterSet Truth::RecordedParameters(const ident::Model& model) const {
  ident::ParameterSet p = Parameters(model);
  if (const int zero = p.position_of_index(39); zero >= 0) p.values()[zero] = sensors.force.offset;
  return p;
}

bool TopOutContact::IsValid(std::string* error) const {
  if (!(stiffness >= 0.0) || !std::isfinite(stiffness)) {
    if (error) *error = fmt::format("stiffness {} N/m must be zero (no stop) or positive", stiffness);
    return false;
  }
  if (!(dissipation >= 0.0) || !std::isfinite(dissipation)) {
    if (error) *error = fmt::format("dissipation {} s/m must not be negative", dissipation);
    return false;
  }
  return true;
}

double Truth::TopOutReading() const {
  const ident::Model model = BuildModel(ident::Causality::kStrokeInput);
  const ident::ParameterSet p = Parameters(model);
  const int offset = p.position_of_index(12);
  const double theta12 = offset >= 0 ? p.value(offset) : 0.0;
  return (1.0 + sensors.stroke.gain_error) * theta12 + sensors.stroke.offset;
}

void Truth::Validate() const {
  std::string error;
  if (!top_out.IsValid(&error)) throw TruthError(fmt::format("{}: [top_out] {}", source, error));
  if (has_effect("gas-solubility") && !has_effect("heat-exchange"))
    throw TruthError(fmt::format("{}: [effects] gas-solubility needs heat-exchange", source));
  if (!actuator.IsValid(&error)) throw TruthError(fmt::format("{}: [actuator] {}", source, error));
  if (!sensors.IsValid(&error)) throw TruthError(fmt::format("{}: [sensors] {}", source, error));
  if (!acquisition.IsValid(&error)) throw TruthError(fmt::format("{}: [acquisition] {}", source, error));
  for (const auto& f : faults)
    if (!f.IsValid(&error)) throw TruthError(fmt::format("{}: [[faults]] {}", source, error));
}

Truth ParseTruth(std::string_view text, const std::string& source_name) { return Reader(source_name).Read(text); }

Truth ReadTruthFile(const std::string& path) {
  return ParseTruth(daq::TomlReader<TruthError>::ReadFile(path, "the truth file"), path);
}

Truth DefaultTruth() { return ParseTruth(DefaultTruthText(), "<built-in default truth>"); }

}  // namespace strut::sim
