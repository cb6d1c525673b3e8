#include "strut/batch/results.h"

#include <fmt/format.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>

#include "strut/daq/atomic_file.h"
#include "text_file.h"

namespace strut::batch {
namespace fs = std::filesystem;
namespace {

constexpr const char* kPlanFile = "plan.json";

std::string NewId() {
  std::random_device device;
  return fmt::format("{:08x}{:08x}", device(), device());
}

std::string HostName() {
  char name[256] = {};
  return gethostname(name, sizeof name - 1) == 0 ? name : "";
}

std::string Cell(const nlohmann::json& v) {
  if (v.is_string()) return v.get<std::string>();
  if (v.is_null()) return "";
  return v.dump();
}

bool IsPairList(const nlohmann::json& a) {
  if (a.empty()) return false;
  for (const auto& e : a)
    if (!e.is_array() || e.size() != 2 || !e[0].is_string() || e[1].is_structured()) return false;
  return true;
}

void FlattenInto(const nlohmann::json& j, const std::string& prefix, std::vector<std::pair<std::string, std::string>>& out) {
  if (j.is_object()) {
    for (const auto& [k, v] : j.items())
      if (!(prefix.empty() && k == "timing")) FlattenInto(v, prefix + k + ".", out);
    return;
  }
  const std::string name = prefix.substr(0, prefix.size() - 1);
  if (j.is_array() && IsPairList(j)) {
    for (const auto& e : j) out.emplace_back(name + "." + e[0].get<std::string>(), Cell(e[1]));
    return;
  }
  if (j.is_array()) {
    bool scalars = true;
    for (const auto& e : j) scalars = scalars && !e.is_structured();
    if (!scalars) {
      out.emplace_back(name, j.dump());
      return;
    }
    std::string joined;
    for (const auto& e : j) joined += (joined.empty() ? "" : "+") + Cell(e);
    out.emplace_back(name, joined);
    return;
  }
  out.emplace_back(name, Cell(j));
}

std::string Quoted(const std::string& cell) {
  if (cell.find_first_of(",\"\n") == std::string::npos) return cell;
  std::string q = "\"";
  for (char c : cell) q += c == '"' ? std::string("\"\"") : std::string(1, c);
  return q + "\"";
}

nlohmann::json WithoutTiming(nlohmann::json item) {
  item.erase("timing");
  return item;
}

}  // namespace

std::vector<std::pair<std::string, std::string>> Flatten(const nlohmann::json& record) {
  std::vector<std::pair<std::string, std::string>> out;
  FlattenInto(record, "", out);
  return out;
}

std::string Csv(const std::vector<nlohmann::json>& records) {
  std::vector<std::string> columns;
  std::vector<std::map<std::string, std::string>> rows;
  for (const nlohmann::json& r : records) {
    std::map<std::string, std::string> row;
    for (auto& [name, cell] : Flatten(r)) {
      if (std::find(columns.begin(), columns.end(), name) == columns.end()) columns.push_back(name);
      row[name] = std::move(cell);
    }
    rows.push_back(std::move(row));
  }
  std::string text;
  for (std::size_t c = 0; c < columns.size(); ++c) text += (c ? "," : "") + Quoted(columns[c]);
  text += "\n";
  for (const auto& row : rows) {
    for (std::size_t c = 0; c < columns.size(); ++c) {
      const auto it = row.find(columns[c]);
      text += (c ? "," : "") + (it == row.end() ? std::string() : Quoted(it->second));
    }
    text += "\n";
  }
  return text;
}

ResultsFolder ResultsFolder::Prepare(const std::string& path, Plan plan, bool force) {
  std::error_code ec;
  const fs::path dir(path), plan_file = dir / kPlanFile;
  if (fs::exists(plan_file, ec)) {
    ResultsFolder old = Open(path);
    if (SameJobs(old.plan_, plan)) return old;  // the same jobs: go on where it stopped
    if (!force)
      throw BatchError(fmt::format("{}: holds the results of other jobs (from {}); give another folder, or --force to "
                                   "discard them",
                                   path, old.plan_.manifest));
    fs::remove_all(dir / "shards", ec);
    fs::remove_all(dir / "slurm", ec);
  } else if (fs::exists(dir, ec)) {
    if (!fs::is_directory(dir, ec)) throw BatchError(fmt::format("{}: exists and is no folder", path));
    if (!fs::is_empty(dir, ec))
      throw BatchError(fmt::format("{}: a folder that holds files and no batch (no {}); give a new or empty folder",
                                   path, kPlanFile));
  } else if (!fs::create_directories(dir, ec)) {
    throw BatchError(fmt::format("{}: cannot create the results folder: {}", path, ec.message()));
  }
  if (!fs::create_directories(dir / "shards", ec) && ec)
    throw BatchError(fmt::format("{}: cannot create {}: {}", path, (dir / "shards").string(), ec.message()));
  plan.id = NewId();
  try {
    daq::WriteFileAtomically(plan_file.string(), ToJson(plan).dump(1) + "\n");
  } catch (const daq::FileWriteError& e) {
    throw BatchError(e.what());
  }
  return ResultsFolder(fs::absolute(dir).lexically_normal().string(), std::move(plan));
}

ResultsFolder ResultsFolder::Open(const std::string& path) {
  const std::string file = (fs::path(path) / kPlanFile).string();
  if (!fs::exists(file)) throw BatchError(fmt::format("{}: no batch results folder (no {})", path, kPlanFile));
  try {
    return ResultsFolder(fs::absolute(path).lexically_normal().string(), PlanFromJson(nlohmann::json::parse(ReadText(file))));
  } catch (const nlohmann::json::exception& e) {
    throw BatchError(fmt::format("{}: not a batch plan: {}", file, e.what()));
  }
}

std::string ResultsFolder::ShardPath(const ShardId& id) const {
  return fmt::format("{}/shards/{}.{:05}.json", path_, id.job, id.shard);
}

std::optional<nlohmann::json> ResultsFolder::Record(const ShardId& id) const {
  const std::string path = ShardPath(id);
  if (!fs::exists(path)) return std::nullopt;
  try {
    return nlohmann::json::parse(ReadText(path));
  } catch (const nlohmann::json::exception& e) {  // written atomically, so only by hand: say which
    throw BatchError(fmt::format("{}: not a shard record: {}", path, e.what()));
  }
}

std::vector<ShardId> ResultsFolder::Pending() const {
  std::vector<ShardId> out;
  for (const ShardId& id : AllShards(plan_)) {
    const auto r = Record(id);
    if (!r || r->value("status", "") != "ok") out.push_back(id);
  }
  return out;
}

void ResultsFolder::Write(const ShardId& id, const nlohmann::json& record) const {
  daq::WriteFileAtomically(ShardPath(id), record.dump() + "\n");
}

nlohmann::json RunShard(const Plan& plan, const JobRunner& runner, const ShardId& id) {
  const JobSpec& job = plan.Job(id.job);
  const int first = job.ShardFirst(id.shard), count = job.ShardCount(id.shard);
  nlohmann::json record{{"job", id.job}, {"shard", id.shard}, {"first", first}, {"count", count},
                        {"host", HostName()}, {"status", "ok"}};
  nlohmann::json items = nlohmann::json::array();
  const auto start = std::chrono::steady_clock::now();
  for (int k = first; k < first + count; ++k) {
    try {
      nlohmann::json item = runner.RunItem(k);
      item["index"] = k;
      items.push_back(std::move(item));
    } catch (const std::exception& e) {
      // The shard's boundary: whatever its item threw is its error, reported with the item, and
      // the batch's other shards go on (a batch runs thousands of sessions nobody has looked at).
      // A session's reader names its file already: the item's name is not said twice.
      const std::string item = runner.ItemName(k), what = e.what();
      record["status"] = "failed";
      record["error"] = what.rfind(item, 0) == 0 ? what : fmt::format("{}: {}", item, what);
      break;
    }
  }
  record["seconds"] = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (record["status"] == "ok") record["items"] = std::move(items);
  return record;
}

Collected Collect(const ResultsFolder& folder) {
  Collected out;
  const Plan& plan = folder.plan();
  nlohmann::json jobs = nlohmann::json::array();
  std::string timing = "job,shard,host,items,seconds\n";
  for (const JobSpec& job : plan.jobs) {
    std::vector<nlohmann::json> items;
    bool complete = true;
    for (int s = 0; s < job.Shards(); ++s) {
      const ShardId id{job.name, s};
      const auto r = folder.Record(id);
      if (!r) {
        out.missing.push_back(id);
        complete = false;
        continue;
      }
      if (r->value("status", "") != "ok") {
        out.failed.push_back(id);
        out.errors[id] = r->value("error", "");
        complete = false;
        continue;
      }
      out.done.push_back(id);
      timing += fmt::format("{},{},{},{},{}\n", job.name, s, r->value("host", ""), r->at("count").get<int>(),
                            r->at("seconds").dump());
      for (const nlohmann::json& item : r->at("items")) items.push_back(item);
    }
    const auto runner = MakeRunner(job, plan.id);
    const std::string table = runner->Table(items, complete);
    out.tables.emplace_back(job.name, table);
    std::vector<nlohmann::json> results;
    for (const nlohmann::json& item : items) results.push_back(WithoutTiming(item));
    jobs.push_back({{"name", job.name}, {"kind", job.kind}, {"items", job.Items()}, {"complete", complete},
                    {"results", results}});
    daq::WriteFileAtomically(fmt::format("{}/{}.csv", folder.path(), job.name), Csv(results));
    daq::WriteFileAtomically(fmt::format("{}/{}.txt", folder.path(), job.name), table);
  }
  daq::WriteFileAtomically(folder.path() + "/results.json", nlohmann::json{{"jobs", jobs}}.dump(1) + "\n");
  daq::WriteFileAtomically(folder.path() + "/timing.csv", timing);
  return out;
}

}  // namespace strut::batch
