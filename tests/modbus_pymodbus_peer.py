#!/usr/bin/python3
"""A Modbus peer strut did not write: pymodbus drives strut's controller server through the
registers documented in docs/register-map.md, decoding and encoding with pymodbus's own payload
builder and CRC. Usage: modbus_pymodbus_peer.py PORT. Prints one JSON object; exits 1 on a
failed check (with the reason on stderr)."""
import json
import math
import sys

from pymodbus.client import ModbusTcpClient
from pymodbus.constants import Endian
from pymodbus.payload import BinaryPayloadBuilder, BinaryPayloadDecoder
from pymodbus.utilities import computeCRC

UNIT = 1


def check(condition, what):
    if not condition:
        print("pymodbus peer: " + what, file=sys.stderr)
        sys.exit(1)


def decoder(registers):
    return BinaryPayloadDecoder.fromRegisters(registers, byteorder=Endian.Big, wordorder=Endian.Big)


def read_status(client):
    rr = client.read_input_registers(0, 16, slave=UNIT)
    check(not rr.isError(), "reading input registers 0-15: %s" % rr)
    d = decoder(rr.registers)
    status = {}
    for name in ("state", "mode", "status_word", "fault_word", "applied_sequence", "heartbeat"):
        status[name] = d.decode_16bit_uint()
    for name in ("stroke", "force", "command"):
        status[name] = d.decode_32bit_float()
    status["cycles"] = d.decode_32bit_uint()
    status["time_ms"] = d.decode_32bit_uint()
    return status


def read_refusal(client):
    rr = client.read_input_registers(16, 62, slave=UNIT)
    check(not rr.isError(), "reading the refusal registers: %s" % rr)
    text = b"".join(r.to_bytes(2, "big") for r in rr.registers[2:]).split(b"\0")[0].decode("ascii")
    return {"code": rr.registers[0], "register": rr.registers[1], "text": text}


def set_point_block(sequence, mode, ramp, values):
    """Registers 0-19: mode, ramp_cycles, 8 float32 (high word first), checksum, sequence."""
    b = BinaryPayloadBuilder(byteorder=Endian.Big, wordorder=Endian.Big)
    b.add_16bit_uint(mode)
    b.add_16bit_uint(ramp)
    for v in values:
        b.add_32bit_float(v)
    registers = b.to_registers()
    data = b"".join(r.to_bytes(2, "big") for r in registers) + sequence.to_bytes(2, "big")
    crc = computeCRC(data)  # pymodbus gives the RTU wire order (low byte first): swap it
    checksum = ((crc & 0xFF) << 8) | (crc >> 8)
    return registers + [checksum, sequence]


def main():
    port = int(sys.argv[1])
    client = ModbusTcpClient("127.0.0.1", port=port, timeout=3)
    check(client.connect(), "cannot connect to 127.0.0.1:%d" % port)
    out = {}
    out["status_before"] = read_status(client)

    # A whole set-point block in one write_multiple_registers, committed by a new sequence.
    sequence = (out["status_before"]["applied_sequence"] + 1) & 0xFFFF or 1
    values = [0.12, 0.02, 1.5, 0.01, 0.0, 0.3, -40000.0, 40000.0]
    block = set_point_block(sequence, 1, 4, values)
    rr = client.write_registers(0, block, slave=UNIT)
    check(not rr.isError(), "writing the set-point block: %s" % rr)
    check(read_status(client)["applied_sequence"] == sequence, "the set-point was not applied")
    out["sequence"] = sequence

    # Half a block and a commit whose checksum does not match: refused with exception 3.
    torn = set_point_block(sequence + 1, 1, 4, [0.12, 0.05, 1.5, 0.01, 0.0, 0.3, -40000.0, 40000.0])
    rr = client.write_registers(0, torn[:10], slave=UNIT)
    check(not rr.isError(), "staging half a block: %s" % rr)
    rr = client.write_register(19, sequence + 1, slave=UNIT)
    check(rr.isError() and getattr(rr, "exception_code", None) == 3,
          "a commit with a stale checksum was not refused with exception 3: %s" % rr)
    out["torn_refusal"] = read_refusal(client)
    check(read_status(client)["applied_sequence"] == sequence, "a torn block was applied")

    # A NaN amplitude with a correct checksum: refused, naming holding register 4.
    nan_block = set_point_block(sequence + 2, 1, 4, [0.12, math.nan, 1.5, 0.01, 0.0, 0.3, -40000.0, 40000.0])
    rr = client.write_registers(0, nan_block, slave=UNIT)
    check(rr.isError() and getattr(rr, "exception_code", None) == 3, "a NaN amplitude was not refused: %s" % rr)
    out["nan_refusal"] = read_refusal(client)

    # Commands, one register each; run before arm is refused.
    rr = client.write_register(20, 2, slave=UNIT)
    check(rr.isError() and getattr(rr, "exception_code", None) == 3, "run before arm was not refused: %s" % rr)
    out["run_refusal"] = read_refusal(client)
    for command in (1, 2):
        rr = client.write_register(20, command, slave=UNIT)
        check(not rr.isError(), "command %d: %s" % (command, rr))
    # Heartbeat and watchdog, read back.
    rr = client.write_registers(21, [7, 0], slave=UNIT)
    check(not rr.isError(), "heartbeat and watchdog: %s" % rr)
    rr = client.read_holding_registers(0, 23, slave=UNIT)
    check(not rr.isError(), "reading holding registers 0-22: %s" % rr)
    out["holding"] = rr.registers
    # A register outside the map: exception 2.
    rr = client.read_holding_registers(23, 1, slave=UNIT)
    check(rr.isError() and getattr(rr, "exception_code", None) == 2, "register 23 was not refused: %s" % rr)
    out["status_after"] = read_status(client)
    client.close()
    print(json.dumps(out))


if __name__ == "__main__":
    main()
