#!/usr/bin/env python3
"""The virtual board's Modbus TCP driven by pymodbus (a client nobody here wrote).

Usage: plc-modbus-test.py HOST_SIM [--flood-s S] [--json OUT]

Starts `HOST_SIM serve --pty --modbus-tcp 127.0.0.1:0`, commissions it over the serial
link as an integrator would (plc/enable, the heartbeat time, a table uploaded into the
staging bank, the slaves referenced where they are), then runs a PLC's shift over
Modbus: it takes ownership, selects and activates the table, starts (approach, then
following), reads the axis values while following, loses its heartbeat (the axes hold),
and checks every refusal: a write from the non-owner (exception 01), an illegal address
(02), an illegal value (03), a truncated MBAP header, 20 connections at once and a
request flood, whose rate it reports. Exits non-zero on the first failed check.
"""
import json
import os
import socket
import struct
import subprocess
import sys
import time

from pymodbus.client import ModbusTcpClient
from pymodbus.pdu import ExceptionResponse

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TABLE = os.path.join(ROOT, "host-sim", "scenarios", "tangent_board.csv")

# Registers (docs/plc.md, `host-sim modbus-map`).
CMD, CMD_AXIS, HEARTBEAT, OWNER, SELECT = 0, 1, 2, 3, 4
PARAM_ID, PARAM_OP, PARAM_VALUE, PARAM_AXIS = 10, 11, 12, 14
ST_STATUS, ST_STATE, ST_ACK, ST_COUNT, ST_ACTIVE = 0, 1, 4, 5, 6
ST_PARAM_RESULT = 7
ENABLE, START, STOP, HOLD, ACTIVATE = 1, 2, 4, 8, 1 << 9
BIT_OWNER_IS_PLC, BIT_HEARTBEAT_LOST = 1 << 6, 1 << 7
IDLE, FOLLOWING, HOLDING, MANUAL = 0, 1, 2, 4


def check(cond, what):
    if not cond:
        print(f"FAIL: {what}", file=sys.stderr)
        sys.exit(1)
    print(f"ok: {what}")


def i32(hi, lo):
    return struct.unpack(">i", struct.pack(">HH", hi, lo))[0]


def f32_words(v):
    return list(struct.unpack(">HH", struct.pack(">f", v)))


class Board:
    def __init__(self, host_sim):
        self.host_sim = host_sim
        self.proc = subprocess.Popen(
            [host_sim, "serve", "--pty", "--modbus-tcp", "127.0.0.1:0"],
            stdout=subprocess.PIPE,
            text=True,
        )
        self.pty = self.proc.stdout.readline().strip()
        line = self.proc.stdout.readline().strip()
        check(line.startswith("modbus-tcp: "), f"serve prints the Modbus address ({line})")
        host, port = line.split(": ", 1)[1].rsplit(":", 1)
        self.addr = (host, int(port))

    def cli(self, *args, ok=True):
        r = subprocess.run(
            [self.host_sim, *args, "--port", self.pty], capture_output=True, text=True
        )
        if ok and r.returncode != 0:
            print(r.stdout, r.stderr, file=sys.stderr)
            check(False, f"host-sim {' '.join(args)}")
        return r

    def status(self):
        return json.loads(self.cli("status", "--json").stdout)

    def close(self):
        self.proc.kill()
        self.proc.wait()


def client(b):
    c = ModbusTcpClient(b.addr[0], port=b.addr[1], timeout=2, retries=0)
    check(c.connect(), "a client connects")
    return c


def input_regs(c, a, n):
    r = c.read_input_registers(a, count=n, slave=1)
    assert not r.isError(), r
    return r.registers


def exc(r):
    return r.exception_code if isinstance(r, ExceptionResponse) else None


def main():
    host_sim = sys.argv[1]
    flood_s = float(sys.argv[sys.argv.index("--flood-s") + 1]) if "--flood-s" in sys.argv else 20.0
    out = sys.argv[sys.argv.index("--json") + 1] if "--json" in sys.argv else None
    b = Board(host_sim)
    figures = {}
    try:
        # plc/enable is off by default: a connection is closed at once.
        s = socket.create_connection(b.addr, timeout=2)
        s.sendall(bytes([0, 1, 0, 0, 0, 6, 1, 4, 0, 0, 0, 1]))
        try:
            got = s.recv(64)
        except ConnectionResetError:
            got = b""
        s.close()
        check(got == b"", "with plc/enable 0 the board does not answer")

        # Commissioning over the serial link (the host owns the machine meanwhile).
        b.cli("param", "set", "plc/enable", "1")
        b.cli("param", "set", "plc/heartbeat_ms", "300")
        b.cli("upload", TABLE, "--id", "7")
        st = b.status()
        for k in range(2):
            pos = st["axes"][k]["pos_mm"]
            b.cli("motion", "set-position", "--axis", str(k), "--mm", str(pos))
        check(b.status().get("owner") == "host", "the serial host owns the board it configured")

        c = client(b)
        # Every input register of the map reads.
        mp = json.loads(subprocess.run([host_sim, "modbus-map", "--json", "--axes", "2"],
                                       capture_output=True, text=True, check=True).stdout)
        for r in mp:
            n = 1 if r["type"] in ("u16", "i16") else 2
            fn = c.read_input_registers if r["table"] == "input" else c.read_holding_registers
            rr = fn(r["address"], count=n, slave=1)
            check(not rr.isError(), f"read {r['name']} at {r['address']}")

        # The non-owner is refused with 01 and nothing changes.
        r = c.write_register(CMD, ENABLE | START, slave=1)
        check(exc(r) == 1, "a command from the PLC while the host owns the board: exception 01")
        check(input_regs(c, ST_STATE, 1)[0] == IDLE, "… and nothing moved")
        # Illegal address and value.
        check(exc(c.read_input_registers(30, count=1, slave=1)) == 2, "a gap: exception 02")
        check(exc(c.read_input_registers(101, count=1, slave=1)) == 2, "half an i32: exception 02")
        check(exc(c.write_register(OWNER, 5, slave=1)) == 3, "owner 5: exception 03")

        # Take ownership (the machine is idle), with a heartbeat.
        hb = 1
        c.write_registers(HEARTBEAT, [hb, 2], slave=1)
        check(input_regs(c, ST_STATUS, 1)[0] & BIT_OWNER_IS_PLC, "the PLC owns the machine")
        check(b.status().get("owner") == "plc", "host-sim status shows the PLC as owner")
        r = b.cli("motion", "start", ok=False)
        check(r.returncode != 0, "the serial host's Start is refused while the PLC owns")

        # A setting through the parameter channel: out of range → 03, then a good one.
        kp_id = 1
        r = c.write_registers(PARAM_ID, [kp_id, 2] + f32_words(5000.0) + [0], slave=1)
        check(exc(r) == 3, "kp 5000 through param.value: exception 03")
        check(input_regs(c, ST_PARAM_RESULT, 1)[0] == 3, "param.result says out of range")
        r = c.write_registers(PARAM_ID, [kp_id, 1] + f32_words(0.0) + [0], slave=1)
        check(not r.isError(), "kp read through the channel")
        kp = struct.unpack(">f", struct.pack(">HH", *input_regs(c, 8, 2)))[0]
        check(abs(kp - b_kp(b)) < 1e-6, f"param.read_value is the board's kp ({kp})")

        # Select and activate the table, then start: approach, then follow.
        c.write_register(SELECT, 7, slave=1)
        r = c.write_register(CMD, ENABLE | ACTIVATE, slave=1)
        check(not r.isError(), "activate_table")
        check(input_regs(c, ST_ACTIVE, 1)[0] == 7, "table.active_id is 7")
        c.write_registers(100, [0, 0, 0, 20_000], slave=1)  # axis 0 approach at 20 mm/s
        r = c.write_register(CMD, ENABLE, slave=1)
        r = c.write_register(CMD, ENABLE | START, slave=1)
        check(not r.isError(), "start")
        t0 = time.time()
        state = None
        while time.time() - t0 < 30:
            hb += 1
            c.write_register(HEARTBEAT, hb & 0xFFFF, slave=1)
            state = input_regs(c, ST_STATE, 1)[0]
            if state == FOLLOWING:
                break
            time.sleep(0.05)
        check(state == FOLLOWING, "the axes follow after the approach")
        worst = 0
        for _ in range(20):
            hb += 1
            c.write_register(HEARTBEAT, hb & 0xFFFF, slave=1)
            a = input_regs(c, 100, 6)
            worst = max(worst, abs(i32(a[4], a[5])))
            check(abs(i32(a[0], a[1]) + i32(a[4], a[5]) - i32(a[2], a[3])) <= 1,
                  "axis 0: target = actual + error") if _ == 0 else None
            time.sleep(0.05)
        figures["following_error_max_um"] = worst
        check(worst < 1000, f"axis 0 follows within 1 mm while read over Modbus ({worst} µm)")

        # Heartbeat loss: silence for longer than plc/heartbeat_ms holds the axes.
        time.sleep(0.6)
        st = input_regs(c, ST_STATUS, 2)
        check(st[1] == HOLDING, f"heartbeat lost: the axes hold (state {st[1]})")
        check(st[0] & BIT_HEARTBEAT_LOST, "status shows heartbeat_lost")

        # A truncated MBAP header, then a garbage one: the board keeps serving.
        s = socket.create_connection(b.addr, timeout=2)
        s.sendall(bytes([0, 1, 0]))
        s.close()
        s = socket.create_connection(b.addr, timeout=2)
        s.sendall(bytes([0, 1, 0x12, 0x34, 0, 6, 1, 4, 0, 0, 0, 1]))
        try:
            got = s.recv(64)
        except ConnectionResetError:
            got = b""
        s.close()
        check(got == b"", "a header with another protocol id is dropped with its connection")
        check(len(input_regs(c, 0, 2)) == 2, "the board still answers")

        # 20 connections at once.
        cs = [ModbusTcpClient(b.addr[0], port=b.addr[1], timeout=2, retries=0) for _ in range(20)]
        check(all(x.connect() for x in cs), "20 clients connect")
        check(all(not x.read_input_registers(0, count=12, slave=1).isError() for x in cs),
              "20 clients read at once")
        for x in cs:
            x.close()

        # A request flood: 10-register reads as fast as one client can.
        n, t0 = 0, time.time()
        while time.time() - t0 < flood_s:
            r = c.read_input_registers(100, count=10, slave=1)
            check(not r.isError(), "a flood read") if n == 0 else None
            if r.isError():
                check(False, "a flood read failed")
            n += 1
        dt = time.time() - t0
        figures["tcp_requests_per_s"] = round(n / dt, 1)
        figures["flood_s"] = round(dt, 1)
        st = b.status()
        figures["tick_overruns_after_flood"] = st.get("overruns")
        check(b.status()["state"] is not None, "the serial link still answers after the flood")
        print(f"flood: {n} requests in {dt:.1f} s = {n / dt:.0f} req/s")
        c.close()
    finally:
        b.close()
    if out:
        with open(out, "w") as f:
            json.dump(figures, f, indent=2)
    print(json.dumps(figures))


def b_kp(b):
    r = json.loads(b.cli("param", "get", "axis/0/kp_lsb_per_um", "--json").stdout)
    return r["value"]


if __name__ == "__main__":
    main()
