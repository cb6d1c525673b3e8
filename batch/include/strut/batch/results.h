// A batch's results folder (docs/batch.md): plan.json (the frozen plan), shards/JOB.NNNNN.json (one
// JSON line per finished or failed shard, written atomically), and what Collect merges from them:
// JOB.csv, JOB.txt (the study table), results.json, timing.csv.
#pragma once

#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "strut/batch/jobs.h"
#include "strut/batch/plan.h"

namespace strut::batch {

class ResultsFolder {
 public:
  //! Creates `path` for `plan`, or opens it to go on where an earlier run of the same jobs stopped.
  //! A folder that holds other jobs is refused unless `force` (its shards are then discarded); a
  //! folder that is no batch's and not empty is refused always. Writes plan.json before any work,
  //! so an unwritable folder fails here. Throws BatchError naming the folder.
  static ResultsFolder Prepare(const std::string& path, Plan plan, bool force);
  //! Opens an existing results folder (an array task, --collect); throws BatchError naming it.
  static ResultsFolder Open(const std::string& path);

  const Plan& plan() const { return plan_; }
  const std::string& path() const { return path_; }
  std::string ShardPath(const ShardId& id) const;
  //! The shard's record; nullopt when it has none (never run, or stopped before it ended).
  std::optional<nlohmann::json> Record(const ShardId& id) const;
  //! Shards without a successful record (never run, stopped, or failed), in plan order.
  std::vector<ShardId> Pending() const;
  //! Writes the shard's record atomically (one JSON line).
  void Write(const ShardId& id, const nlohmann::json& record) const;

 private:
  ResultsFolder(std::string path, Plan plan) : path_(std::move(path)), plan_(std::move(plan)) {}
  std::string path_;
  Plan plan_;
};

//! Runs shard `id` of `plan` with `runner` (its job's): the items in order. The record holds each
//! item's result, or, when an item throws, status "failed" and the error naming the item; it never
//! throws for an item's error, so one failed shard does not stop the others.
nlohmann::json RunShard(const Plan& plan, const JobRunner& runner, const ShardId& id);

//! What the shards of a folder hold.
struct Collected {
  std::vector<ShardId> done, failed, missing;
  std::map<ShardId, std::string> errors;  //!< of the failed shards
  std::vector<std::pair<std::string, std::string>> tables;  //!< job, its table
  bool Complete() const { return failed.empty() && missing.empty(); }
};

//! Merges the folder's shard records into JOB.csv, JOB.txt, results.json and timing.csv (written
//! atomically; results.json and the CSV hold no timing, so they are the same wherever and however
//! split the shards ran).
Collected Collect(const ResultsFolder& folder);

//! One record's results as CSV cells: objects flattened to "a.b", lists of scalars joined with
//! "+", lists of [key, value] pairs as columns "list.key"; "timing" left out.
std::vector<std::pair<std::string, std::string>> Flatten(const nlohmann::json& record);
//! The records as CSV: the union of their columns in order of first appearance.
std::string Csv(const std::vector<nlohmann::json>& records);

}  // namespace strut::batch
