// The runners of the two families of jobs (jobs.cpp picks one).
#pragma once

#include "strut/batch/jobs.h"

namespace strut::batch {

std::unique_ptr<JobRunner> MakeStudyRunner(const JobSpec& job);
std::unique_ptr<JobRunner> MakeSessionRunner(const JobSpec& job, const std::string& batch_id);

}  // namespace strut::batch
