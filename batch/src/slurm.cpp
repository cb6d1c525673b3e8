#include "strut/batch/slurm.h"

#include <fmt/format.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <thread>
#include <fstream>
#include <sstream>

#include "strut/daq/atomic_file.h"
#include "text_file.h"

extern char** environ;

namespace strut::batch {
namespace fs = std::filesystem;
namespace {

struct ProgramResult {
  int exit_code = -1;
  std::string output;  //!< stdout and stderr
};

//! Runs `argv` (looked up on PATH) and waits; throws BatchError when it cannot be started.
ProgramResult RunProgram(const std::vector<std::string>& argv) {
  int pipe_fds[2];
  if (pipe(pipe_fds) != 0) throw BatchError("cannot make a pipe to run " + argv.front());
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, pipe_fds[1], 1);
  posix_spawn_file_actions_adddup2(&actions, pipe_fds[1], 2);
  posix_spawn_file_actions_addclose(&actions, pipe_fds[0]);
  std::vector<char*> args;
  for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  pid_t pid = -1;
  const int rc = posix_spawnp(&pid, argv.front().c_str(), &actions, nullptr, args.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  close(pipe_fds[1]);
  ProgramResult result;
  if (rc != 0) {
    close(pipe_fds[0]);
    throw BatchError(fmt::format("cannot run {}: {} (is Slurm installed and on PATH?)", argv.front(), strerror(rc)));
  }
  char buffer[4096];
  for (ssize_t n; (n = read(pipe_fds[0], buffer, sizeof buffer)) > 0;) result.output.append(buffer, n);
  close(pipe_fds[0]);
  int status = 0;
  waitpid(pid, &status, 0);
  result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  return result;
}

//! A word for a shell script, single-quoted.
std::string Shell(const std::string& word) {
  std::string q = "'";
  for (char c : word) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

std::string Trim(std::string s) {
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.pop_back();
  return s;
}

}  // namespace

std::string TasksText(const std::vector<ShardId>& shards, int shards_per_task) {
  std::string text;
  for (std::size_t k = 0; k < shards.size(); ++k)
    text += shards[k].Text() + ((k + 1) % shards_per_task == 0 || k + 1 == shards.size() ? "\n" : " ");
  return text;
}

std::vector<ShardId> TaskShards(const Plan& plan, const std::string& tasks_file, int index) {
  std::ifstream in(tasks_file);
  if (!in) throw BatchError(fmt::format("{}: cannot open the tasks file", tasks_file));
  std::string line;
  for (int k = 0; std::getline(in, line); ++k)
    if (k == index) {
      std::vector<ShardId> out;
      std::istringstream words(line);
      for (std::string w; words >> w;) out.push_back(ParseShard(plan, w));
      return out;
    }
  throw BatchError(fmt::format("{}: no line for task {}", tasks_file, index));
}

std::string SbatchScript(const ResultsFolder& folder, const std::string& tasks_file, int tasks,
                         const SlurmOptions& options, const std::string& strut) {
  std::string s = "#!/bin/bash\n# A strut batch as a Slurm job array (docs/batch.md): task N runs line N of the tasks file.\n";
  s += fmt::format("#SBATCH --job-name=strut-batch\n#SBATCH --array=0-{}\n", tasks - 1);
  s += fmt::format("#SBATCH --output={}/slurm/task-%A_%a.log\n", folder.path());
  s += "#SBATCH --ntasks=1\n#SBATCH --cpus-per-task=1\n";
  if (!options.partition.empty()) s += fmt::format("#SBATCH --partition={}\n", options.partition);
  if (!options.time_limit.empty()) s += fmt::format("#SBATCH --time={}\n", options.time_limit);
  s += fmt::format("exec {} batch --task-file {} --task-index \"$SLURM_ARRAY_TASK_ID\"\n", Shell(strut), Shell(tasks_file));
  return s;
}

Submission SubmitArray(const ResultsFolder& folder, const std::vector<ShardId>& shards, const SlurmOptions& options,
                       const std::string& strut) {
  if (shards.empty()) throw BatchError("nothing to submit: every shard has its result");
  const fs::path dir = fs::path(folder.path()) / "slurm";
  std::error_code ec;
  fs::create_directories(dir, ec);
  int n = 0;
  while (fs::exists(dir / fmt::format("array-{}.sh", n))) ++n;
  Submission sub;
  sub.tasks_file = (dir / fmt::format("array-{}.tasks", n)).string();
  sub.script = (dir / fmt::format("array-{}.sh", n)).string();
  const int per = std::max(1, options.shards_per_task);
  sub.tasks = static_cast<int>((shards.size() + per - 1) / per);
  daq::WriteFileAtomically(sub.tasks_file, TasksText(shards, per));
  daq::WriteFileAtomically(sub.script, SbatchScript(folder, sub.tasks_file, sub.tasks, options, strut));
  std::vector<std::string> argv{"sbatch", "--parsable"};
  for (const std::string& a : options.sbatch_args) argv.push_back(a);
  argv.push_back(sub.script);
  const ProgramResult r = RunProgram(argv);
  if (r.exit_code != 0) throw BatchError(fmt::format("sbatch {} failed ({}): {}", sub.script, r.exit_code, Trim(r.output)));
  const std::string out = Trim(r.output);
  sub.job_id = out.substr(out.rfind('\n') + 1);
  sub.job_id = sub.job_id.substr(0, sub.job_id.find(';'));  // "id;cluster" on a federation
  const std::string jobs = (dir / "jobs").string();
  daq::WriteFileAtomically(jobs, ReadText(jobs) + sub.job_id + "\n");
  return sub;
}

std::vector<std::string> ActiveJobs(const ResultsFolder& folder) {
  std::vector<std::string> active;
  std::istringstream jobs(ReadText(folder.path() + "/slurm/jobs"));
  for (std::string id; std::getline(jobs, id);) {
    if (id.empty()) continue;
    const ProgramResult r = RunProgram({"squeue", "-h", "-r", "-j", id, "-o", "%i"});
    // squeue forgets a finished job after MinJobAge and then fails with "Invalid job id": gone.
    if (r.exit_code == 0 && !Trim(r.output).empty()) active.push_back(id);
  }
  return active;
}

void WaitForArrays(const ResultsFolder& folder, double poll, const std::function<void(const Progress&)>& on_progress) {
  const auto start = std::chrono::steady_clock::now();
  const int before = static_cast<int>(folder.Pending().size());
  for (;;) {
    std::this_thread::sleep_for(std::chrono::duration<double>(poll));
    const int pending = static_cast<int>(folder.Pending().size());
    const bool active = !ActiveJobs(folder).empty();
    Progress p;
    p.total = folder.plan().Shards();
    p.done = p.total - pending;
    p.elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    const int finished = before - pending;
    p.eta = finished > 0 ? p.elapsed / finished * pending : -1.0;
    if (on_progress) on_progress(p);
    if (pending == 0 || !active) return;
  }
}

std::string ThisExecutable() {
  std::error_code ec;
  const fs::path self = fs::read_symlink("/proc/self/exe", ec);
  if (ec) throw BatchError("cannot find this program's path (/proc/self/exe): " + ec.message());
  return self.string();
}

}  // namespace strut::batch
