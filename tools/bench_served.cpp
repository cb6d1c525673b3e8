// strut bench served: the README's two-process pair, `strut rig serve-sim` and `strut rig run
// --rig modbus-tcp://... --daq udp:...`, run again and again as separate processes of this
// binary: how many runs of the standard matrix complete without a trip, and how far the stream
// ever lagged behind its clock. docs/simulated-rig.md "Keeping time".
#include <fmt/format.h>
#include <netinet/in.h>
#include <signal.h>
#include <spawn.h>
#include <spdlog/spdlog.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fcntl.h>

#include <algorithm>
#include <cstring>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <regex>
#include <sstream>
#include <thread>

#include "commands.h"
#include "option_checks.h"
#include "output_files.h"

extern char** environ;

namespace strut::tools {
namespace {

using Clock = std::chrono::steady_clock;
namespace fs = std::filesystem;

// A free loopback port: bound to port 0 and released (the pair binds it a moment later).
int FreePort(int type) {
  const int s = socket(AF_INET, type, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t size = sizeof a;
  if (s < 0 || bind(s, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0 ||
      getsockname(s, reinterpret_cast<sockaddr*>(&a), &size) != 0)
    throw std::runtime_error(fmt::format("bench served: no free loopback port: {}", std::strerror(errno)));
  close(s);
  return ntohs(a.sin_port);
}

bool Listening(int port) {
  const int s = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  a.sin_port = htons(static_cast<std::uint16_t>(port));
  const bool ok = connect(s, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0;
  close(s);
  return ok;
}

// This binary with `args`, its stdout and stderr to files.
pid_t Spawn(const std::vector<std::string>& args, const std::string& out, const std::string& err) {
  posix_spawn_file_actions_t files;
  posix_spawn_file_actions_init(&files);
  posix_spawn_file_actions_addopen(&files, 1, out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_addopen(&files, 2, err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  const std::string self = fs::read_symlink("/proc/self/exe").string();
  std::vector<char*> argv{const_cast<char*>(self.c_str())};
  for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  pid_t pid = 0;
  const int r = posix_spawn(&pid, self.c_str(), &files, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&files);
  if (r != 0) throw std::runtime_error(fmt::format("bench served: cannot start {}: {}", self, std::strerror(r)));
  return pid;
}

int Wait(pid_t pid) {
  int status = 0;
  waitpid(pid, &status, 0);
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

std::string ReadText(const std::string& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

std::optional<double> Figure(const std::string& text, const std::regex& pattern) {
  std::optional<double> last;
  for (auto it = std::sregex_iterator(text.begin(), text.end(), pattern); it != std::sregex_iterator(); ++it)
    last = std::stod((*it)[1]);
  return last;
}

struct ServedRun {
  int exit_code = 0;
  double wall = 0.0;
  std::optional<double> lag;     // s the samples arrived behind their clock, at most (the runner's)
  std::optional<double> behind;  // s the served rig was behind its schedule, at most (serve-sim's)
  std::string cause;
};

struct BenchServed {
  int runs = 20;
  int parallel = 1;
  double speed = 50.0;
  unsigned long draw = 4242;
  std::string dir, json_path;

  ServedRun RunPair(int index, const fs::path& where) const {
    const int modbus = FreePort(SOCK_STREAM), can = FreePort(SOCK_DGRAM);
    const std::string tag = std::to_string(index), speed_text = fmt::format("{:g}", speed);
    const std::string draw_text = std::to_string(draw);
    const pid_t server = Spawn({"rig", "serve-sim", "--listen", fmt::format("127.0.0.1:{}", modbus), "--can",
                                fmt::format("udp:127.0.0.1:{}", can), "--speed", speed_text, "--draw", draw_text},
                               (where / ("serve-" + tag + ".out")).string(), (where / ("serve-" + tag + ".log")).string());
    const auto started = Clock::now();
    while (!Listening(modbus) && Clock::now() - started < std::chrono::seconds(10))
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    ServedRun r;
    const auto t0 = Clock::now();
    const pid_t runner = Spawn({"rig", "run", "--speed", speed_text, "--draw", draw_text, "--rig",
                                fmt::format("modbus-tcp://127.0.0.1:{}", modbus), "--daq",
                                fmt::format("udp:127.0.0.1:{}", can), "--no-progress", "--force", "-o",
                                (where / ("run-" + tag + ".h5")).string()},
                               (where / ("run-" + tag + ".out")).string(), (where / ("run-" + tag + ".log")).string());
    r.exit_code = Wait(runner);
    r.wall = std::chrono::duration<double>(Clock::now() - t0).count();
    kill(server, SIGTERM);
    Wait(server);
    const std::string log = ReadText((where / ("run-" + tag + ".log")).string());
    r.lag = Figure(log, std::regex(R"(arrived at most ([0-9.]+) s behind)"));
    r.behind = Figure(ReadText((where / ("serve-" + tag + ".log")).string()), std::regex(R"(behind by at most ([0-9.]+) s)"));
    std::smatch m;
    const std::string out = ReadText((where / ("run-" + tag + ".out")).string());
    if (std::regex_search(out, m, std::regex(R"(cause: ([^\n]*))"))) r.cause = m[1];
    for (const char* f : {".h5", ".h5.journal"}) fs::remove(where / ("run-" + tag + f));
    return r;
  }

  void Run() {
    const fs::path where = fs::path(dir.empty() ? fs::temp_directory_path().string() : dir) /
                           fmt::format("strut-bench-served-{}", getpid());
    fs::create_directories(where);
    std::vector<ServedRun> results(static_cast<std::size_t>(runs));
    spdlog::info("bench served: {} runs of the standard matrix, {} pair(s) at once, --speed {:g}, --draw {}; logs in {}",
                 runs, parallel, speed, draw, where.string());
    for (int first = 0; first < runs; first += parallel) {
      std::vector<std::thread> pairs;
      for (int i = first; i < std::min(runs, first + parallel); ++i)
        pairs.emplace_back([&, i] { results[static_cast<std::size_t>(i)] = RunPair(i + 1, where); });
      for (std::thread& t : pairs) t.join();
      for (int i = first; i < std::min(runs, first + parallel); ++i) {
        const ServedRun& r = results[static_cast<std::size_t>(i)];
        spdlog::info("run {}: exit {} in {:.1f} s{}", i + 1, r.exit_code, r.wall, r.cause.empty() ? "" : ": " + r.cause);
      }
    }
    int complete = 0;
    double worst_lag = 0.0, worst_behind = 0.0;
    nlohmann::json json{{"runs", runs}, {"parallel", parallel}, {"speed", speed}, {"draw", draw}};
    std::cout << fmt::format("{:>4} {:>5} {:>7} {:>7} {:>8}  {}\n", "run", "exit", "wall s", "lag s", "behind s", "cause");
    for (std::size_t i = 0; i < results.size(); ++i) {
      const ServedRun& r = results[i];
      complete += r.exit_code == 0 ? 1 : 0;
      worst_lag = std::max(worst_lag, r.lag.value_or(0.0));
      worst_behind = std::max(worst_behind, r.behind.value_or(0.0));
      const auto text = [](const std::optional<double>& v) { return v ? fmt::format("{:.3f}", *v) : std::string("-"); };
      std::cout << fmt::format("{:>4} {:>5} {:>7.1f} {:>7} {:>8}  {}\n", i + 1, r.exit_code, r.wall, text(r.lag),
                               text(r.behind), r.cause);
      json["results"].push_back({{"exit_code", r.exit_code},
                                 {"wall_s", r.wall},
                                 {"largest_lag_s", r.lag ? nlohmann::json(*r.lag) : nlohmann::json(nullptr)},
                                 {"server_behind_s", r.behind ? nlohmann::json(*r.behind) : nlohmann::json(nullptr)},
                                 {"cause", r.cause}});
    }
    std::cout << fmt::format("\ncomplete without a trip: {} of {}; the samples at most {:.3f} s behind their clock, the "
                             "served rig at most {:.3f} s behind its schedule\n",
                             complete, runs, worst_lag, worst_behind);
    json["complete"] = complete;
    json["largest_lag_s"] = worst_lag;
    json["server_behind_s"] = worst_behind;
    if (!json_path.empty()) WriteJsonOutput(json_path, json);
    if (complete == runs) fs::remove_all(where);
  }
};

}  // namespace

void RegisterBenchServed(CLI::App& bench) {
  auto [sub, command] = AddCommand<BenchServed>(
      bench, "served",
      "The two-process simulated rig of the README (strut rig serve-sim and strut rig run as separate processes) run "
      "again and again: runs that complete without a trip, and how far the stream lagged");
  sub->add_option("--runs", command->runs, "Runs of the standard matrix.")->check(Between(1, 1000))->capture_default_str();
  sub->add_option("--parallel", command->parallel, "Pairs run at once (more load on the machine).")
      ->check(Between(1, 16))
      ->capture_default_str();
  sub->add_option("--speed", command->speed, "The pair's --speed.")->check(Between(0.01, 1000.0))->capture_default_str();
  sub->add_option("--draw", command->draw, "The drawn unit both processes serve and record (--draw of both).")
      ->capture_default_str();
  sub->add_option("--dir", command->dir, "Where the runs' logs go (default: the temp directory; kept when a run failed).");
  sub->add_option("--json", command->json_path, "Also write the figures as JSON.");
}

}  // namespace strut::tools
