#include "strut/sim/recorded_truth.h"

#include <algorithm>
#include <fmt/format.h>

#include "strut/ident/model.h"

namespace strut::sim {
namespace {

daq::MetadataGroup Group(std::string name) {
  daq::MetadataGroup g;
  g.name = std::move(name);
  return g;
}

}  // namespace

void RecordTruth(const Truth& truth, daq::Session& session) {
  const ident::Model model = truth.BuildModel(ident::Causality::kStrokeInput);
  RecordTruth(truth, truth.RecordedParameters(model), model.composition(), session);
}

std::vector<daq::MetadataGroup> TruthMetadata(const Truth& truth) {
  daq::Session holder;
  RecordTruth(truth, holder);
  return holder.metadata;
}

void RecordTruth(const Truth& truth, const ident::ParameterSet& parameters, const std::string& composition,
                 daq::Session& session) {
  daq::MetadataGroup root = Group(std::string(kTruthGroup));
  root.attributes["composition"] = composition;
  root.attributes["source"] = truth.source;
  root.attributes["drawn"] = static_cast<long long>(truth.drawn ? 1 : 0);
  if (truth.drawn) {
    const DrawRecord& d = *truth.drawn;
    // int64 holds the seed's bits; ReadRecordedTruth casts back (seeds >= 2^63 read negative in h5py).
    root.attributes["seed"] = static_cast<long long>(d.seed);
    root.attributes["base"] = d.base;
    root.attributes["around"] = d.around;
    root.attributes["attempts"] = static_cast<long long>(d.attempts);
    daq::MetadataGroup effects = Group("effects");
    for (const EffectSize& e : d.effects) {
      daq::MetadataGroup g = Group(e.effect);
      g.attributes["parameter"] = e.parameter;
      g.attributes["size"] = e.size;
      g.attributes["given"] = static_cast<long long>(e.given ? 1 : 0);
      effects.groups.push_back(std::move(g));
    }
    root.groups.push_back(std::move(effects));
  }
  daq::MetadataGroup values = Group("parameters");
  for (int i = 0; i < parameters.size(); ++i) {
    const ident::ParameterSpec& spec = parameters.spec(i);
    daq::MetadataGroup g = Group(spec.key());
    g.attributes["name"] = spec.name;
    g.attributes["unit"] = spec.unit;
    g.attributes["value"] = parameters.value(i);
    values.groups.push_back(std::move(g));
  }
  root.groups.push_back(std::move(values));
  auto& metadata = session.metadata;
  metadata.erase(std::remove_if(metadata.begin(), metadata.end(),
                                [](const daq::MetadataGroup& g) { return g.name == kTruthGroup; }),
                 metadata.end());
  metadata.push_back(std::move(root));
}

std::optional<RecordedTruth> ReadRecordedTruth(const daq::Session& session) {
  const daq::MetadataGroup* root = session.find_metadata(kTruthGroup);
  if (!root) return std::nullopt;
  const std::string file = session.source_path.empty() ? "<memory>" : session.source_path;
  const auto fail = [&](const std::string& item, const std::string& what) {
    return TruthError(fmt::format("{}: group '/truth{}': {}", file, item, what));
  };
  const auto text = [&](const daq::MetadataGroup& g, const std::string& where, const char* name) {
    if (auto t = g.text(name)) return *t;
    throw fail(where, fmt::format("attribute '{}': missing or not a string", name));
  };
  const auto number = [&](const daq::MetadataGroup& g, const std::string& where, const char* name) {
    if (auto v = g.number(name)) return *v;
    throw fail(where, fmt::format("attribute '{}': missing or not a number", name));
  };
  RecordedTruth r;
  r.composition = text(*root, "", "composition");
  r.source = root->text("source").value_or("");
  if (root->number("drawn").value_or(0.0) != 0.0) {
    DrawRecord d;
    const auto seed = root->attributes.find("seed");
    if (seed == root->attributes.end() || !std::holds_alternative<long long>(seed->second))
      throw fail("", "attribute 'seed': missing or not an integer");
    d.seed = static_cast<std::uint64_t>(std::get<long long>(seed->second));
    d.base = text(*root, "", "base");
    d.around = root->text("around").value_or("");
    d.attempts = static_cast<int>(root->number("attempts").value_or(1.0));
    if (const daq::MetadataGroup* effects = root->find_group("effects")) {
      for (const daq::MetadataGroup& g : effects->groups) {
        const std::string where = "/effects/" + g.name;
        d.effects.push_back(
            {g.name, text(g, where, "parameter"), number(g, where, "size"), number(g, where, "given") != 0.0});
      }
    }
    r.drawn = std::move(d);
  }
  ident::Model model = [&] {
    try {
      return ident::Model::Build(r.composition, ident::Causality::kStrokeInput);
    } catch (const ident::ModelError& e) {
      throw fail("", fmt::format("attribute 'composition': {}", e.what()));
    }
  }();
  r.parameters = model.defaults();
  const daq::MetadataGroup* values = root->find_group("parameters");
  if (!values) throw fail("/parameters", "missing");
  std::vector<bool> seen(r.parameters.size(), false);
  for (const daq::MetadataGroup& g : values->groups) {
    const auto position = r.parameters.find(g.name);
    if (!position)
      throw fail("/parameters/" + g.name, fmt::format("the model {} has no such parameter", r.composition));
    r.parameters.values()[*position] = number(g, "/parameters/" + g.name, "value");
    seen[*position] = true;
  }
  for (int i = 0; i < r.parameters.size(); ++i)
    if (!seen[i])
      throw fail("/parameters", fmt::format("{} ({}) of the model {} is missing", r.parameters.spec(i).key(),
                                            r.parameters.spec(i).name, r.composition));
  return r;
}

}  // namespace strut::sim
