#include "strut/batch/engine.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <map>
#include <memory>
#include <mutex>
#include <thread>

namespace strut::batch {
namespace {

std::string Duration(double s) {
  const long t = std::lround(s);
  if (t >= 3600) return fmt::format("{}h{:02}m", t / 3600, t / 60 % 60);
  if (t >= 60) return fmt::format("{}m{:02}s", t / 60, t % 60);
  return fmt::format("{}s", t);
}

std::map<std::string, std::unique_ptr<JobRunner>> Runners(const Plan& plan, const std::vector<ShardId>& shards) {
  std::map<std::string, std::unique_ptr<JobRunner>> runners;
  for (const ShardId& id : shards)
    if (!runners.count(id.job)) runners[id.job] = MakeRunner(plan.Job(id.job), plan.id);
  return runners;
}

}  // namespace

std::string ProgressLine(const Progress& p) {
  constexpr int kWidth = 24;
  const int filled = p.total > 0 ? (p.done + p.failed) * kWidth / p.total : kWidth;
  return fmt::format("[{}{}] {}/{} done, {} failed, {} running, {}", std::string(filled, '#'),
                     std::string(kWidth - filled, '.'), p.done, p.total, p.failed, p.running,
                     p.eta < 0 ? std::string("time to go unknown") : Duration(p.eta) + " to go");
}

void RunLocal(const ResultsFolder& folder, const std::vector<ShardId>& shards, int threads,
              const std::function<void(const Progress&)>& on_progress) {
  const Plan& plan = folder.plan();
  const auto runners = Runners(plan, shards);
  Progress progress;
  progress.total = plan.Shards();
  progress.done = progress.total - static_cast<int>(folder.Pending().size());
  std::mutex lock;
  std::atomic<std::size_t> next{0};
  int finished_now = 0;
  const auto start = std::chrono::steady_clock::now();
  const auto report = [&] {  // under `lock`
    progress.elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    const int left = static_cast<int>(shards.size()) - finished_now;
    progress.eta = finished_now > 0 ? progress.elapsed / finished_now * left : -1.0;
    if (on_progress) on_progress(progress);
  };
  {
    std::lock_guard<std::mutex> guard(lock);
    report();
  }
  const auto work = [&] {
    for (std::size_t k; (k = next++) < shards.size();) {
      const ShardId& id = shards[k];
      {
        std::lock_guard<std::mutex> guard(lock);
        ++progress.running;
      }
      const nlohmann::json record = RunShard(plan, *runners.at(id.job), id);
      folder.Write(id, record);
      std::lock_guard<std::mutex> guard(lock);
      --progress.running;
      ++finished_now;
      if (record.at("status") == "ok")
        ++progress.done;
      else {
        ++progress.failed;
        spdlog::error("shard {} failed: {}", id.Text(), record.value("error", ""));
      }
      report();
    }
  };
  std::vector<std::thread> pool;
  const int n = std::max(1, std::min<int>(threads, static_cast<int>(shards.size())));
  for (int t = 0; t < n; ++t) pool.emplace_back(work);
  for (std::thread& t : pool) t.join();
}

void RunShards(const ResultsFolder& folder, const std::vector<ShardId>& shards) {
  const Plan& plan = folder.plan();
  const auto runners = Runners(plan, shards);
  for (const ShardId& id : shards) {
    const auto old = folder.Record(id);
    if (old && old->value("status", "") == "ok") {
      spdlog::info("shard {}: done already", id.Text());
      continue;
    }
    const nlohmann::json record = RunShard(plan, *runners.at(id.job), id);
    folder.Write(id, record);
    if (record.at("status") == "ok")
      spdlog::info("shard {}: done in {:.2f} s", id.Text(), record.at("seconds").get<double>());
    else
      spdlog::error("shard {} failed: {}", id.Text(), record.value("error", ""));
  }
}

}  // namespace strut::batch
