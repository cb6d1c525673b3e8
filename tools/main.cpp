// strut: shaker testing and identification of nonlinear dampers.
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <exception>
#include <malloc.h>

#include "commands.h"
#include "option_checks.h"
#include "qc_commands.h"
#include "output_files.h"

int main(int argc, char** argv) {
  // Keep freed memory in the heap instead of handing it back to the kernel: a fit allocates the same
  // multi-megabyte sensitivity matrices every iteration, and fresh pages (mmap, page faults) were a
  // fifth of its time. The largest threshold glibc takes (32 MiB) and a trim far above the working set.
  mallopt(M_MMAP_THRESHOLD, 32 * 1024 * 1024);
  mallopt(M_TRIM_THRESHOLD, 1024 * 1024 * 1024);
  CLI::App app{"strut: shaker testing and identification of landing-gear dampers"};
  app.require_subcommand(1);
  app.formatter(strut::tools::HelpFormatter());  // subcommands added below inherit it
  app.set_version_flag("--version", "strut 0.1.0");
  int verbosity = 0;
  bool quiet = false;
  app.add_flag("-v,--verbose", verbosity, "Log more (-v: debug messages; -vv: traces too).");
  app.add_flag("-q,--quiet", quiet, "Log only warnings and errors.");
  app.parse_complete_callback([&] {
    if (quiet) {
      spdlog::set_level(spdlog::level::warn);
    } else if (verbosity >= 2) {
      spdlog::set_level(spdlog::level::trace);
    } else if (verbosity == 1) {
      spdlog::set_level(spdlog::level::debug);
    } else {
      spdlog::set_level(spdlog::level::info);
    }
  });
  // Logs go to stderr: stdout carries data (tables, JSON).
  spdlog::set_default_logger(spdlog::stderr_color_mt("strut"));
  spdlog::set_pattern("%^[%l]%$ %v");

  strut::tools::RegisterInfoCommand(app);
  strut::tools::RegisterPeriodicCommand(app);
  strut::tools::RegisterDemoCommand(app);
  strut::tools::RegisterIdentifyCommand(app);
  strut::tools::RegisterDiscoverCommand(app);
  strut::tools::RegisterBenchCommand(app);
  strut::tools::RegisterBenchDiscover(*app.get_subcommand("bench"));
  strut::tools::RegisterBenchUnits(*app.get_subcommand("bench"));
  strut::tools::RegisterBenchStrokeZero(*app.get_subcommand("bench"));
  strut::tools::RegisterBenchConfusion(*app.get_subcommand("bench"));
  strut::tools::RegisterBenchQc(*app.get_subcommand("bench"));
  strut::tools::RegisterBenchDrop(*app.get_subcommand("bench"));
  strut::tools::RegisterBenchDropFit(*app.get_subcommand("bench"));
  strut::tools::RegisterSimCommand(app);
  strut::tools::RegisterImportCommand(app);
  strut::tools::RegisterRigCommand(app);
  strut::tools::RegisterRigRunCommand(*app.get_subcommand("rig"));
  strut::tools::RegisterRecoverCommand(app);
  strut::tools::RegisterReplayCommand(app);
  strut::tools::RegisterBenchReplay(*app.get_subcommand("bench"));
  strut::tools::RegisterBenchRig(*app.get_subcommand("bench"));
  strut::tools::RegisterBenchServed(*app.get_subcommand("bench"));
  strut::tools::RegisterQcCommand(app);
  strut::tools::RegisterPredictCommand(app);
  strut::tools::RegisterBatchCommand(app);
  strut::tools::RegisterBenchBatch(*app.get_subcommand("bench"));

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // --help and --version end with 0; every refused command line with 1, the exit code of an
    // error (README "Exit codes"), not CLI11's own 100s.
    return app.exit(e) == 0 ? 0 : 1;
  } catch (const strut::tools::ExitCode& e) {
    return e.code();
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return 1;
  }
  return 0;
}
