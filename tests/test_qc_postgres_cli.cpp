// The QC history on a real PostgreSQL server (initdb and pg_ctl as the postgres user in a temporary
// folder, tests/support/servers/postgres.sh): 8 processes write 200 decisions at once, each also
// written by a second process under the same key: 200 rows, none twice, and `strut qc history`
// prints what it prints for the same decisions in SQLite. A server stopped while rigs write gives
// a clear error and leaves no decision half-written. A password never shows.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fmt/format.h>

#include <chrono>
#include <functional>
#include <fstream>
#include <nlohmann/json.hpp>
#include <regex>
#include <set>
#include <sstream>
#include <thread>

#include "lot_sessions.h"
#include "servers.h"
#include "strut/qc/history.h"
#include "strut_cli.h"

namespace strut::qc {
namespace {

constexpr const char* kPassword = "Dz7-secret-pw";

//! Decision k of the test: its serial, time, verdict and two quantities all of k.
Decision Numbered(int k) {
  Decision d;
  d.serial = fmt::format("SN-{:03}", k);
  d.session = fmt::format("/archive/unit-{:03}.h5", k);
  d.reference = "ref.toml";
  d.model = "2dof+viscous-damping";
  d.verdict = k % 7 == 0 ? Verdict::kFail : Verdict::kPass;
  if (k % 7 == 0) d.reasons = {"charge pressure out of band", "a second reason"};
  d.quantities = {{{"charge_pressure", "Pa", "", 7.0e5 + 1.0 / 3.0 * k, 1e3}, 6.9e5, 6.5e5, 7.5e5, Status::kIn, "gas"},
                  {{"friction", "N", "", 300.0 + 0.1 * k, NAN}, NAN, NAN, NAN, Status::kUntoleranced, ""}};
  return d;
}
std::string TimeOf(int k) { return fmt::format("2026-11-{:02}T{:02}:{:02}:00Z", 1 + k / 100, k / 60 % 24, k % 60); }

//! Runs `body` in `n` child processes (index 0..n-1) at once; their exit codes.
std::vector<int> InProcesses(int n, const std::function<int(int)>& body) {
  std::vector<pid_t> pids;
  for (int i = 0; i < n; ++i) {
    const pid_t pid = fork();
    if (pid == 0) _exit(body(i));
    pids.push_back(pid);
  }
  std::vector<int> codes;
  for (pid_t pid : pids) {
    int status = 0;
    waitpid(pid, &status, 0);
    codes.push_back(WIFEXITED(status) ? WEXITSTATUS(status) : 100);
  }
  return codes;
}

//! `qc history` output with the ids (which depend on who wrote first) taken out.
std::string WithoutIds(const std::string& text, bool json) {
  if (json) {
    nlohmann::json j = nlohmann::json::parse(text.substr(text.find('{')));
    for (auto& d : j["decisions"]) d.erase("id");
    return j.dump(1);
  }
  return std::regex_replace(text, std::regex("(^|\n) *\\d+  "), "$1");
}

class Postgres : public ::testing::Test {
 protected:
  void SetUp() override {
    const test::ShellResult r = test::Shell(Script("start") + " " + kPassword, dir_.file("start"));
    started_ = true;
    std::smatch m;
    if (r.exit_code != 0 || !std::regex_search(r.out, m, std::regex("PORT=(\\d+)"))) {
      reason_ = "a PostgreSQL server could not start: " + r.out + r.err;
      return;
    }
    url_ = "postgresql://strut@127.0.0.1:" + std::string(m[1]) + "/qc";
    setenv("PGPASSWORD", kPassword, 1);  // where libpq looks, as on a rig
  }
  void TearDown() override {
    if (started_) test::Shell(Script("stop"), dir_.file("stop"));
    unsetenv("PGPASSWORD");
  }
  std::string Script(const std::string& command) const {
    return std::string(test::kServersDir) + "/postgres.sh " + command + " " + dir_.file("pg");
  }
  test::TempDir dir_;
  bool started_ = false;
  std::string reason_, url_;
};

TEST_F(Postgres, EightRigsWriteAtOnceNothingLostOrTwiceAndHistoryReadsAsSqlite) {
  if (!reason_.empty()) STRUT_SERVER_UNAVAILABLE(reason_);
  { History create(url_); }  // the schema once, before the rigs (each would make it otherwise, in turn)
  // Decision k is written by process k % 8 and again by process (k + 1) % 8, under one key.
  const std::vector<int> codes = InProcesses(8, [&](int p) {
    try {
      History h(url_);
      int inserted = 0;
      for (int k = 0; k < 200; ++k)
        if (k % 8 == p || (k + 1) % 8 == p) inserted += h.Record(Numbered(k), TimeOf(k), fmt::format("rig:{}", k)).inserted;
      return inserted > 50 ? 99 : 0;
    } catch (const HistoryError&) {
      return 98;
    }
  });
  for (int c : codes) EXPECT_EQ(c, 0);
  const History pg(url_);
  const std::vector<HistoryEntry> entries = pg.Query();
  ASSERT_EQ(entries.size(), 200u);
  std::set<std::string> keys;
  for (const HistoryEntry& e : entries) {
    keys.insert(e.key);
    EXPECT_EQ(e.quantities.size(), 2u) << e.serial;
  }
  EXPECT_EQ(keys.size(), 200u);
  EXPECT_EQ(entries[5].quantities[0].quantity.value, 7.0e5 + 1.0 / 3.0 * 5);  // doubles exact through the server

  {
    History sqlite(dir_.file("qc.db"));
    for (int k = 199; k >= 0; --k) sqlite.Record(Numbered(k), TimeOf(k), fmt::format("rig:{}", k));
  }
  for (const std::string& options : {std::string(""), std::string(" --json"), std::string(" --serial SN-014"),
                                     std::string(" --since 2026-11-02")}) {
    const auto a = test::RunStrut("qc history --db " + url_ + options);
    const auto b = test::RunStrut("qc history --db " + dir_.file("qc.db") + options);
    ASSERT_EQ(a.exit_code, 0) << a.output;
    ASSERT_EQ(b.exit_code, 0) << b.output;
    EXPECT_EQ(WithoutIds(a.output, !options.empty() && options == " --json"),
              WithoutIds(b.output, !options.empty() && options == " --json"))
        << options;
  }

  // A night's re-check through strut batch lands in the same history.
  daq::WriteSession(dir_.file("unit.h5"), test::QcSession(900, study::Defect::kNone, 900));
  ASSERT_EQ(test::RunStrut("qc plan --write-reference " + dir_.file("ref.toml") + " >/dev/null").exit_code, 0);
  std::ofstream(dir_.file("night.toml")) << "[[job]]\nkind = \"qc\"\nsessions = [\"unit.h5\"]\nreference = "
                                            "\"ref.toml\"\ndb = \"" << url_ << "\"\n";
  const auto night = test::RunStrut("batch " + dir_.file("night.toml"));
  ASSERT_EQ(night.exit_code, 0) << night.output;
  const auto lot = pg.Query(std::string("LOT-000900"));
  ASSERT_EQ(lot.size(), 1u);
  EXPECT_EQ(lot[0].verdict, "PASS");
  EXPECT_EQ(lot[0].key.rfind("batch:", 0), 0u);

  // The password: never from the command line, never in a message.
  const std::string with_password = std::regex_replace(url_, std::regex("strut@"), std::string("strut:") + kPassword + "@");
  const auto refused = test::RunStrut("qc history --db " + with_password);
  EXPECT_EQ(refused.exit_code, 1);
  EXPECT_NE(refused.output.find("holds a password"), std::string::npos) << refused.output;
  EXPECT_EQ(refused.output.find(kPassword), std::string::npos) << refused.output;
  const test::ShellResult bad = test::Shell("PGPASSWORD=not-it " + std::string(test::kStrutBinary) +
                                                " qc history --db " + url_,
                                            dir_.file("bad"));
  EXPECT_EQ(bad.exit_code, 1);
  EXPECT_NE(bad.err.find(url_ + ": cannot connect to the QC history"), std::string::npos) << bad.err;
  EXPECT_NE(bad.err.find("password authentication failed"), std::string::npos) << bad.err;
}

TEST_F(Postgres, ServerStoppedWhileRigsWriteGivesAClearErrorAndNothingHalfWritten) {
  if (!reason_.empty()) STRUT_SERVER_UNAVAILABLE(reason_);
  { History create(url_); }
  const std::string report = dir_.file("report");
  std::thread stopper([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(700));
    test::Shell(Script("stop") + " immediate", dir_.file("stop-mid"));  // as a crash of the server leaves it
  });
  const std::vector<int> codes = InProcesses(4, [&](int p) {
    int recorded = 0;
    std::string error;
    try {
      History h(url_);
      for (int k = p; k < 100000; k += 4) {
        h.Record(Numbered(k % 1000), TimeOf(k % 1000), fmt::format("stop:{}", k));
        ++recorded;
      }
    } catch (const HistoryError& e) {
      error = e.what();
    }
    std::ofstream(fmt::format("{}.{}", report, p)) << recorded << "\n" << error << "\n";
    return error.empty() ? 1 : 0;
  });
  stopper.join();
  for (int c : codes) EXPECT_EQ(c, 0) << "a rig wrote on with the server stopped";
  long reported = 0;
  for (int p = 0; p < 4; ++p) {
    std::ifstream in(fmt::format("{}.{}", report, p));
    long n = 0;
    std::string blank, error;
    in >> n;
    std::getline(in, blank);
    std::getline(in, error);
    reported += n;
    EXPECT_NE(error.find(url_ + ": the decision for serial SN-"), std::string::npos) << error;
    EXPECT_NE(error.find("was not recorded"), std::string::npos) << error;
    EXPECT_EQ(error.find(kPassword), std::string::npos);
  }
  EXPECT_GT(reported, 0);
  ASSERT_EQ(test::Shell(Script("restart"), dir_.file("restart")).exit_code, 0);
  const std::vector<HistoryEntry> entries = History(url_).Query();
  // Every decision a rig was told was recorded is there; a commit whose reply the crash took may be
  // there too (at most one per rig); none is there in part.
  EXPECT_GE(static_cast<long>(entries.size()), reported);
  EXPECT_LE(static_cast<long>(entries.size()), reported + 4);
  for (const HistoryEntry& e : entries) EXPECT_EQ(e.quantities.size(), 2u) << e.key;
}

}  // namespace
}  // namespace strut::qc
