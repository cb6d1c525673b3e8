// What a batch runs (docs/batch.md): the manifest's jobs, each split into shards of a few items
// (drawn units or sessions). An item's seed is the study's own (first seed + unit index), so the
// results do not depend on how a job is split or where its shards run.
#pragma once

#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>
#include <vector>

namespace strut::batch {

//! A manifest, plan or results folder that cannot be used; the message names the file (and line).
class BatchError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

//! The job kinds: over sessions, or a drawn-unit study.
inline constexpr const char* kSessionKinds[] = {"identify", "discover", "qc"};
inline constexpr const char* kStudyKinds[] = {"confusion", "units", "qc-lot", "drop"};

struct JobSpec {
  std::string name, kind;
  int per_shard = 1;  //!< items (units or sessions) per shard
  // Drawn-unit studies, as the bench command's options of the same names.
  int units = 10;
  unsigned long first_seed = 0;  //!< 0: the bench command's default for the kind
  std::string base = "2dof";
  std::vector<std::string> effects;
  bool servo = false;
  std::string sizes = "drawn";  //!< confusion: drawn or study
  double start_off = 0.3;       //!< units
  int effects_per_unit = 0;     //!< units
  bool fit_truth = false;       //!< units
  int defects = 3;              //!< qc-lot: defective units per ten
  double mass = 350.0, velocity = 0.5, duration = 30.0;  //!< drop: kg, m/s at contact, s from contact
  // Session jobs: the sessions (absolute, in order) after the manifest's globs were expanded.
  std::vector<std::string> sessions;
  std::string model = "2dof", input = "stroke";
  std::string reference;  //!< qc: the reference file (absolute)
  std::string db;         //!< qc: the QC history the decisions go to ("" none): a path or a postgresql:// URL

  bool IsStudy() const;
  int Items() const;   //!< units (confusion: per effect times effects) or sessions
  int Shards() const;  //!< ceil(Items / per_shard)
  //! The items of shard `s`: [first, first + count).
  int ShardFirst(int s) const { return s * per_shard; }
  int ShardCount(int s) const;
};

//! A batch's frozen plan: the manifest's jobs with globs expanded, stored in the results folder so
//! that a task on another machine runs exactly what was planned.
struct Plan {
  std::string id;        //!< made when the folder is created: part of every QC decision's key
  std::string manifest;  //!< its path, for messages
  std::vector<JobSpec> jobs;
  const JobSpec& Job(const std::string& name) const;  //!< throws BatchError for an unknown name
  int Shards() const;
};

//! One shard of one job.
struct ShardId {
  std::string job;
  int shard = 0;
  std::string Text() const;  //!< "job/3"
  bool operator<(const ShardId& o) const { return job != o.job ? job < o.job : shard < o.shard; }
  bool operator==(const ShardId& o) const { return job == o.job && shard == o.shard; }
};
//! Every shard of the plan, job by job.
std::vector<ShardId> AllShards(const Plan& plan);
//! "job/3" back to a shard of `plan`; throws BatchError naming `text`.
ShardId ParseShard(const Plan& plan, const std::string& text);

//! Reads a manifest (TOML, docs/batch.md): jobs checked, globs expanded against the manifest's
//! folder and sorted. A glob that matches nothing, an unknown key or kind, a duplicate job name
//! throw BatchError naming the file and line.
Plan ReadManifest(const std::string& path);

nlohmann::json ToJson(const Plan& plan);
Plan PlanFromJson(const nlohmann::json& j);
//! The same jobs (the id and the manifest's path aside).
bool SameJobs(const Plan& a, const Plan& b);

}  // namespace strut::batch
