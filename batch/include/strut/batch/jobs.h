// What one item of a job does (a drawn unit of a study, a session), and the table its items make.
#pragma once

#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "strut/batch/plan.h"

namespace strut::batch {

//! Runs the items of one job and makes the table of their results. Safe to call from several
//! threads at once: it holds only the job's options.
class JobRunner {
 public:
  virtual ~JobRunner() = default;
  //! Item `index`'s record: what it found, and under "timing" what varies from run to run (seconds).
  //! Throws what the item's work throws (a session that cannot be read, ...).
  virtual nlohmann::json RunItem(int index) const = 0;
  //! The table of the job's items (records in item order): for a study, what its bench command
  //! prints; `complete` false when items are missing (the table says so).
  virtual std::string Table(const std::vector<nlohmann::json>& records, bool complete) const = 0;
  //! The item in words for messages ("unit 2003 (viscous-damping)", a session's path).
  virtual std::string ItemName(int index) const = 0;
};

//! The runner of `job`; `batch_id` makes the keys of the QC decisions a qc job records.
std::unique_ptr<JobRunner> MakeRunner(const JobSpec& job, const std::string& batch_id);

//! The key of a QC decision a batch records: the same for the same session in the same batch, so a
//! shard that runs again (its record lost) does not record the decision twice.
std::string DecisionKey(const std::string& batch_id, const std::string& job, const std::string& session);

}  // namespace strut::batch
