#include "strut/batch/plan.h"

#include <fmt/format.h>
#include <glob.h>

#include <algorithm>
#include <filesystem>
#include <set>

#include "strut/daq/toml_reader.h"

namespace strut::batch {
namespace fs = std::filesystem;
namespace {

using Reader = daq::TomlReader<BatchError>;

bool IsOneOf(const std::string& kind, const auto& kinds) {
  return std::find_if(std::begin(kinds), std::end(kinds), [&](const char* k) { return kind == k; }) != std::end(kinds);
}

std::vector<std::string> Strings(const Reader& r, const toml::table& t, std::string_view where, const char* key) {
  std::vector<std::string> out;
  const toml::node* n = t.get(key);
  if (!n) return out;
  const toml::array* a = n->as_array();
  if (!a) r.Fail(*n, fmt::format("{}{}: expected an array of strings, got {}", where, key, Reader::Describe(*n)));
  for (const toml::node& e : *a) out.push_back(r.Text(e, where, key));
  return out;
}

//! The files a glob names (or the one path it is), relative to `folder`, sorted.
std::vector<std::string> Expand(const Reader& r, const toml::node& at, const fs::path& folder, const std::string& pattern) {
  const std::string full = fs::path(pattern).is_absolute() ? pattern : (folder / pattern).string();
  glob_t g{};
  const int rc = glob(full.c_str(), 0, nullptr, &g);
  std::vector<std::string> out;
  for (std::size_t i = 0; rc == 0 && i < g.gl_pathc; ++i)
    out.push_back(fs::absolute(g.gl_pathv[i]).lexically_normal().string());
  globfree(&g);
  if (out.empty()) r.Fail(at, fmt::format("sessions: '{}' matches no file (looked for {})", pattern, full));
  std::sort(out.begin(), out.end());
  return out;
}

JobSpec ReadJob(const Reader& r, const toml::table& t, const fs::path& folder, int index) {
  JobSpec j;
  const std::string where = fmt::format("[[job]] {}: ", index + 1);
  r.RefuseUnknown(t, where,
                  {"name", "kind", "per_shard", "units", "first_seed", "base", "effects", "servo", "sizes", "start_off",
                   "effects_per_unit", "fit_truth", "defects", "mass", "velocity", "duration", "sessions", "model", "input", "reference", "db"});
  const auto kind = r.Text(t, where, "kind");
  if (!kind) r.Fail(t, where + "kind is missing (identify, discover, qc, confusion, units, qc-lot or drop)");
  j.kind = *kind;
  if (!IsOneOf(j.kind, kSessionKinds) && !IsOneOf(j.kind, kStudyKinds))
    r.Fail(*t.get("kind"), fmt::format("{}kind '{}': give identify, discover, qc, confusion, units, qc-lot or drop", where, j.kind));
  j.name = r.Text(t, where, "name").value_or(j.kind);
  if (j.name.empty() || j.name.find_first_not_of("abcdefghijklmnopqrstuvwxyz0123456789_-") != std::string::npos)
    r.Fail(t, fmt::format("{}name '{}': use lower-case letters, digits, - and _", where, j.name));
  const auto per_shard = r.Integer(t, where, "per_shard").value_or(1);
  if (per_shard < 1 || per_shard > 100000) r.Fail(*t.get("per_shard"), where + "per_shard: give 1 to 100000");
  j.per_shard = static_cast<int>(per_shard);
  if (j.IsStudy()) {
    for (const char* key : {"sessions", "model", "input", "reference", "db"})
      if (t.get(key)) r.Fail(*t.get(key), fmt::format("{}{} belongs to a session job, not a {} study", where, key, j.kind));
    const auto units = r.Integer(t, where, "units").value_or(10);
    if (units < 1 || units > 1000000) r.Fail(*t.get("units"), where + "units: give 1 to 1000000");
    j.units = static_cast<int>(units);
    j.first_seed = static_cast<unsigned long>(r.Integer(t, where, "first_seed")
                                                           .value_or(j.kind == "units" ? 1000 : j.kind == "qc-lot" ? 5000 : 2000));
    j.base = r.Text(t, where, "base").value_or("2dof");
    j.effects = Strings(r, t, where, "effects");
    if (j.kind == "confusion" && j.effects.empty()) j.effects = {"none"};
    j.servo = r.Bool(t, where, "servo").value_or(false);
    j.sizes = r.Text(t, where, "sizes").value_or("drawn");
    if (j.sizes != "drawn" && j.sizes != "study") r.Fail(*t.get("sizes"), where + "sizes: give drawn or study");
    j.start_off = r.Number(t, where, "start_off").value_or(0.3);
    j.effects_per_unit = static_cast<int>(r.Integer(t, where, "effects_per_unit").value_or(0));
    j.fit_truth = r.Bool(t, where, "fit_truth").value_or(false);
    const auto defects = r.Integer(t, where, "defects").value_or(3);
    if (defects < 0 || defects > 10) r.Fail(*t.get("defects"), where + "defects: give 0 to 10 (defective units per ten)");
    j.defects = static_cast<int>(defects);
    j.mass = r.Number(t, where, "mass").value_or(350.0);
    j.velocity = r.Number(t, where, "velocity").value_or(0.5);
    j.duration = r.Number(t, where, "duration").value_or(30.0);
    if (j.mass <= 0) r.Fail(*t.get("mass"), where + "mass: give a number > 0 kg");
    if (j.velocity < 0) r.Fail(*t.get("velocity"), where + "velocity: give a number >= 0 m/s");
    if (j.duration < 0.1 || j.duration > 3600) r.Fail(*t.get("duration"), where + "duration: give 0.1 to 3600 s");
    return j;
  }
  const toml::node* sessions = t.get("sessions");
  if (!sessions) r.Fail(t, where + "sessions is missing (paths or globs, relative to the manifest)");
  for (const std::string& pattern : Strings(r, t, where, "sessions"))
    for (std::string& s : Expand(r, *sessions, folder, pattern)) j.sessions.push_back(std::move(s));
  j.model = r.Text(t, where, "model").value_or("2dof");
  j.input = r.Text(t, where, "input").value_or("stroke");
  if (const auto ref = r.Text(t, where, "reference"))
    j.reference = fs::absolute(folder / *ref).lexically_normal().string();
  if (j.kind == "qc" && j.reference.empty()) r.Fail(t, where + "a qc job needs reference (a golden fit or nominal file)");
  if (const auto db = r.Text(t, where, "db"))
    j.db = db->rfind("postgres", 0) == 0 ? *db : fs::absolute(folder / *db).lexically_normal().string();
  return j;
}

}  // namespace

bool JobSpec::IsStudy() const { return IsOneOf(kind, kStudyKinds); }

int JobSpec::Items() const {
  if (!IsStudy()) return static_cast<int>(sessions.size());
  return kind == "confusion" ? units * static_cast<int>(effects.size()) : units;
}

int JobSpec::Shards() const { return (Items() + per_shard - 1) / per_shard; }
int JobSpec::ShardCount(int s) const { return std::min(per_shard, Items() - ShardFirst(s)); }

const JobSpec& Plan::Job(const std::string& name) const {
  for (const JobSpec& j : jobs)
    if (j.name == name) return j;
  throw BatchError(fmt::format("{}: no job '{}'", manifest, name));
}

int Plan::Shards() const {
  int n = 0;
  for (const JobSpec& j : jobs) n += j.Shards();
  return n;
}

std::string ShardId::Text() const { return fmt::format("{}/{}", job, shard); }

std::vector<ShardId> AllShards(const Plan& plan) {
  std::vector<ShardId> out;
  for (const JobSpec& j : plan.jobs)
    for (int s = 0; s < j.Shards(); ++s) out.push_back({j.name, s});
  return out;
}

ShardId ParseShard(const Plan& plan, const std::string& text) {
  const auto slash = text.rfind('/');
  if (slash == std::string::npos) throw BatchError(fmt::format("shard '{}': expected JOB/INDEX", text));
  ShardId id{text.substr(0, slash), 0};
  try {
    id.shard = std::stoi(text.substr(slash + 1));
  } catch (const std::logic_error&) {
    throw BatchError(fmt::format("shard '{}': expected JOB/INDEX", text));
  }
  const JobSpec& job = plan.Job(id.job);
  if (id.shard < 0 || id.shard >= job.Shards())
    throw BatchError(fmt::format("shard '{}': job {} has shards 0..{}", text, job.name, job.Shards() - 1));
  return id;
}

Plan ReadManifest(const std::string& path) {
  const Reader r(path);
  const toml::table top = r.Parse(Reader::ReadFile(path, "the batch manifest"));
  r.RefuseUnknown(top, "", {"job"});
  Plan plan;
  plan.manifest = path;
  const toml::node* jobs = top.get("job");
  const toml::array* list = jobs ? jobs->as_array() : nullptr;
  if (!list || list->empty()) r.Fail("no [[job]]: a manifest lists at least one job (docs/batch.md)");
  const fs::path folder = fs::absolute(path).parent_path();
  std::set<std::string> names;
  for (std::size_t i = 0; i < list->size(); ++i) {
    const toml::node& n = *list->get(i);
    plan.jobs.push_back(ReadJob(r, r.Table(n, "", "job"), folder, static_cast<int>(i)));
    if (!names.insert(plan.jobs.back().name).second)
      r.Fail(n, fmt::format("[[job]] {}: the name '{}' is taken by an earlier job; give it its own name", i + 1,
                            plan.jobs.back().name));
  }
  return plan;
}

nlohmann::json ToJson(const Plan& plan) {
  nlohmann::json jobs = nlohmann::json::array();
  for (const JobSpec& j : plan.jobs)
    jobs.push_back({{"name", j.name},           {"kind", j.kind},          {"per_shard", j.per_shard},
                    {"units", j.units},         {"first_seed", j.first_seed}, {"base", j.base},
                    {"effects", j.effects},     {"servo", j.servo},        {"sizes", j.sizes},
                    {"start_off", j.start_off}, {"effects_per_unit", j.effects_per_unit},
                    {"fit_truth", j.fit_truth}, {"defects", j.defects}, {"mass", j.mass}, {"velocity", j.velocity},
                    {"duration", j.duration}, {"sessions", j.sessions},  {"model", j.model},
                    {"input", j.input},         {"reference", j.reference}, {"db", j.db}});
  return {{"id", plan.id}, {"manifest", plan.manifest}, {"jobs", jobs}};
}

Plan PlanFromJson(const nlohmann::json& p) {
  Plan plan;
  plan.id = p.at("id").get<std::string>();
  plan.manifest = p.at("manifest").get<std::string>();
  for (const nlohmann::json& x : p.at("jobs")) {
    JobSpec j;
    x.at("name").get_to(j.name);
    x.at("kind").get_to(j.kind);
    x.at("per_shard").get_to(j.per_shard);
    x.at("units").get_to(j.units);
    x.at("first_seed").get_to(j.first_seed);
    x.at("base").get_to(j.base);
    x.at("effects").get_to(j.effects);
    x.at("servo").get_to(j.servo);
    x.at("sizes").get_to(j.sizes);
    x.at("start_off").get_to(j.start_off);
    x.at("effects_per_unit").get_to(j.effects_per_unit);
    x.at("fit_truth").get_to(j.fit_truth);
    x.at("defects").get_to(j.defects);
    x.at("mass").get_to(j.mass);
    x.at("velocity").get_to(j.velocity);
    x.at("duration").get_to(j.duration);
    x.at("sessions").get_to(j.sessions);
    x.at("model").get_to(j.model);
    x.at("input").get_to(j.input);
    x.at("reference").get_to(j.reference);
    x.at("db").get_to(j.db);
    plan.jobs.push_back(std::move(j));
  }
  return plan;
}

bool SameJobs(const Plan& a, const Plan& b) { return ToJson(a).at("jobs") == ToJson(b).at("jobs"); }

}  // namespace strut::batch
