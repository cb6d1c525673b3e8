// A real peer strut did not write: pymodbus (Debian's python3-pymodbus) reads and writes the
// documented registers of strut's controller server; the backend checks what arrived.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "strut/daq/fake_controller.h"
#include "strut/daq/modbus_controller.h"
#include "test_support.h"

namespace strut::daq {
namespace {

double F32(double v) {  // see test_modbus_registers.cpp for why volatile
  volatile float f = static_cast<float>(v);
  return f;
}

TEST(ModbusPymodbus, PymodbusDrivesStrutsServerThroughTheDocumentedRegisters) {
  const test::ShellResult probe = test::Shell("/usr/bin/python3 -c 'import pymodbus.client'", "/dev/null");
  ASSERT_EQ(probe.exit_code, 0) << "python3-pymodbus is missing: run scripts/install-deps.sh";

  FakeControllerBackend backend;
  ControllerStatus status;
  status.stroke = 0.2345;
  status.force = -1500.5;
  status.command = 0.125;
  status.cycles = 77777;
  status.time_ms = 123456789;
  backend.SetStatus(status);
  ModbusControllerServer server(backend);

  test::TempDir dir;
  const test::ShellResult run = test::Shell("timeout 60 /usr/bin/python3 " + std::string(STRUT_SOURCE_DIR) +
                                                "/tests/modbus_pymodbus_peer.py " + std::to_string(server.port()),
                                            dir.file("peer"));
  ASSERT_EQ(run.exit_code, 0) << run.err << run.out;
  const nlohmann::json out = nlohmann::json::parse(run.out);

  // What pymodbus decoded from strut's input registers.
  const nlohmann::json& before = out["status_before"];
  EXPECT_EQ(before["state"], 0);
  EXPECT_EQ(before["mode"], 1);
  EXPECT_EQ(before["applied_sequence"], 0);
  EXPECT_DOUBLE_EQ(before["stroke"].get<double>(), F32(0.2345));
  EXPECT_DOUBLE_EQ(before["force"].get<double>(), -1500.5);
  EXPECT_DOUBLE_EQ(before["command"].get<double>(), 0.125);
  EXPECT_EQ(before["cycles"], 77777);
  EXPECT_EQ(before["time_ms"], 123456789);

  // What strut decoded from pymodbus's set-point block: exactly one applied.
  ASSERT_EQ(backend.applied().size(), 1u);
  const SetPoint s = backend.applied()[0];
  EXPECT_EQ(s.mode, ControlMode::kStroke);
  EXPECT_EQ(s.ramp_cycles, 4);
  EXPECT_EQ(s.static_position, F32(0.12));
  EXPECT_EQ(s.amplitude, F32(0.02));
  EXPECT_EQ(s.frequency, 1.5);
  EXPECT_EQ(s.static_rate, F32(0.01));
  EXPECT_EQ(s.limits.stroke_min, 0.0);
  EXPECT_EQ(s.limits.stroke_max, F32(0.3));
  EXPECT_EQ(s.limits.force_min, -40000.0);
  EXPECT_EQ(s.limits.force_max, 40000.0);
  EXPECT_EQ(out["sequence"], 1);

  // The refusals pymodbus read back name the register and the reason.
  EXPECT_EQ(out["torn_refusal"]["register"], 18);
  EXPECT_NE(out["torn_refusal"]["text"].get<std::string>().find("half-written"), std::string::npos) << out.dump();
  EXPECT_EQ(out["nan_refusal"]["register"], 4);
  EXPECT_NE(out["nan_refusal"]["text"].get<std::string>().find("amplitude"), std::string::npos) << out.dump();
  EXPECT_NE(out["run_refusal"]["text"].get<std::string>().find("not armed"), std::string::npos) << out.dump();

  // Commands arrived in order; heartbeat and watchdog registers hold what was written.
  EXPECT_EQ(backend.commands(), (std::vector<ControllerCommand>{ControllerCommand::kArm, ControllerCommand::kRun}));
  EXPECT_EQ(out["holding"][21], 7);
  EXPECT_EQ(out["holding"][22], 0);
  EXPECT_EQ(out["status_after"]["state"], static_cast<int>(ControllerState::kRunning));
  EXPECT_EQ(out["status_after"]["applied_sequence"], 1);
}

}  // namespace
}  // namespace strut::daq
