#!/usr/bin/python3
"""Every property of PyMeasure's Agilent33500 driver against the mock 33520B.

usage: pymeasure_33500_test.py SERVER_EXE

Starts SERVER_EXE (prints "listening on 127.0.0.1:P", serves until its stdin closes) and drives
it with Debian's python3-pymeasure through pyvisa-py's TCPIP SOCKET resource: each control is
set to a valid value (twice where it takes several forms) and read back, each measurement read,
each setting and method called (Instrument's clear and reset included); after every one of these
the error queue, drained by the driver's check_errors(), must be empty. A few sets out of range or
in conflict must queue the instrument's error codes. Prints a table of the properties tried and
passed; exits non-zero when one fails or when the driver has a property this test does not know
(so a newer PyMeasure cannot pass by skipping).
"""
import math
import subprocess
import sys

from pymeasure.adapters import VISAAdapter
from pymeasure.instruments.agilent.agilent33500 import Agilent33500

IDN = "Keysight Technologies,33520B,MY00000042,4.00-1.19-2.00-58-00"
NO_ERROR = '+0,"No error"'


def close(a, b):
    return math.isclose(float(a), float(b), rel_tol=1e-9, abs_tol=1e-15)


def unquote(v):
    return v.strip('"') if isinstance(v, str) else v


# property -> [(value set, expected read-back)], applied in this order. Values are valid for the
# 33520B in the state the earlier rows leave (1 kHz, 50 ohm load, burst off at the end).
CONTROLS = [
    ("shape", [(s, s) for s in ("SQU", "TRI", "RAMP", "PULS", "PRBS", "NOIS", "ARB", "DC",
                                "SIN")]),
    ("frequency", [(2500.0, 2500.0), (1000.0, 1000.0)]),
    ("amplitude", [(2.0, 2.0), (0.5, 0.5)]),
    ("amplitude_unit", [("VRMS", "VRMS"), ("DBM", "DBM"), ("VPP", "VPP")]),
    ("offset", [(0.25, 0.25), (-1.0, -1.0), (0.0, 0.0)]),
    ("voltage_high", [(1.5, 1.5)]),
    ("voltage_low", [(-0.5, -0.5)]),
    ("square_dutycycle", [(25.0, 25.0), (50.0, 50.0)]),
    ("ramp_symmetry", [(30.0, 30.0), (100.0, 100.0)]),
    ("pulse_period", [(2e-3, 2e-3), (1e-3, 1e-3)]),
    ("pulse_hold", [("DCYC", "DCYC"), ("DCYCLE", "DCYC"), ("WIDTH", "WIDT"), ("WIDT", "WIDT")]),
    ("pulse_width", [(200e-6, 200e-6)]),
    ("pulse_dutycycle", [(25.0, 25.0)]),
    ("pulse_transition", [(50e-9, 50e-9), (10e-9, 10e-9)]),
    # The driver maps the instrument's 1/0 back to the last key of its value map: 'ON'/'OFF'.
    ("output", [(True, "ON"), ("off", "OFF"), ("ON", "ON"), (False, "OFF")]),
    ("output_load", [("INF", 9.9e37), (1000, 1000.0), (50, 50.0)]),
    ("burst_mode", [("GAT", "GAT"), ("GATED", "GAT"), ("TRIGGERED", "TRIG"), ("TRIG", "TRIG")]),
    ("burst_ncycles", [(5, 5), (1, 1)]),
    ("burst_period", [(20e-3, 20e-3), (10e-3, 10e-3)]),
    ("burst_state", [(True, True), (False, False)]),
    ("trigger_source", [("BUS", "BUS"), ("EXTERNAL", "EXT"), ("IMM", "IMM")]),
    ("ext_trig_out", [(True, True), (False, False)]),
    ("arb_advance", [("TRIG", "TRIG"), ("SRATE", "SRAT")]),
    ("arb_filter", [("STEP", "STEP"), ("OFF", "OFF"), ("NORMAL", "NORM")]),
    ("arb_srate", [(1e6, 1e6), (40e3, 40e3)]),
]
MEASUREMENTS = ["id"]
SETTINGS = ["display"]
# arb_file needs an arb in volatile memory: uploaded first with data_arb (a method).
SPECIAL = ["arb_file"]


def start_server(exe):
    server = subprocess.Popen([exe, IDN], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    line = server.stdout.readline().strip()
    if not line.startswith("listening on 127.0.0.1:"):
        server.kill()
        sys.exit(f"FAIL server start: {line!r}")
    return server, int(line.rsplit(":", 1)[1])


def driver_properties():
    """Names of every property of Agilent33500, the ones it inherits from Instrument included
    (a newer PyMeasure adds some there: `complete`, `status`, `options`)."""
    names = []
    for cls in Agilent33500.__mro__:
        if cls is object:
            break
        for name, attr in vars(cls).items():
            if isinstance(attr, property) and name not in names:
                names.append(name)
    return names


class Table:
    def __init__(self):
        self.rows = []

    def add(self, name, tried, passed, note=""):
        self.rows.append((name, tried, passed, note))

    def print(self):
        print(f"{'property':20} {'tried':>5} {'passed':>6}  note")
        for name, tried, passed, note in self.rows:
            print(f"{name:20} {tried:5d} {passed:6d}  {note}")
        tried = sum(r[1] for r in self.rows)
        passed = sum(r[2] for r in self.rows)
        props = len(self.rows)
        ok = sum(1 for r in self.rows if r[1] == r[2] and r[1] > 0)
        print(f"{props} properties, {ok} passed; {tried} round trips, {passed} passed")
        return ok == props


def errors(gen):
    return gen.check_errors()


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    server, port = start_server(sys.argv[1])
    failures = []
    table = Table()
    try:
        adapter = VISAAdapter(f"TCPIP0::127.0.0.1::{port}::SOCKET", visa_library="@py",
                              read_termination="\n", timeout=5000)
        gen = Agilent33500(adapter)

        known = {name for name, _ in CONTROLS} | set(MEASUREMENTS) | set(SETTINGS) | set(SPECIAL)
        unknown = [n for n in driver_properties() if n not in known]
        if unknown:
            failures.append(f"driver properties this test does not cover: {unknown}")
        gen.write("*RST;*CLS")

        for name, cases in CONTROLS:
            passed = 0
            notes = []
            for value, want in cases:
                setattr(gen, name, value)
                got = getattr(gen, name)
                errs = errors(gen)
                same = close(got, want) if isinstance(want, (int, float)) and not isinstance(
                    want, bool) else got == want
                if same and not errs:
                    passed += 1
                else:
                    notes.append(f"{value!r} -> {got!r} {errs}")
                    failures.append(f"{name} = {value!r}: read {got!r}, want {want!r}, "
                                    f"errors {errs}")
            table.add(name, len(cases), passed, "; ".join(notes))

        got = gen.id  # the driver splits the reply at its commas
        errs = errors(gen)
        ok = got == IDN.split(",") and not errs
        table.add("id", 1, int(ok), "" if ok else f"{got!r} {errs}")
        if not ok:
            failures.append(f"id: {got!r}, errors {errs}")

        gen.display = "PYMEASURE"
        shown = gen.ask("DISP:TEXT?").strip()
        gen.clear_display()
        cleared = gen.ask("DISP:TEXT?").strip()
        ok = shown == '"PYMEASURE"' and cleared == '""' and not errors(gen)
        table.add("display", 1, int(ok), "" if ok else f"{shown!r} then {cleared!r}")
        if not ok:
            failures.append(f"display: {shown!r}, after clear {cleared!r}")

        def method(label, call):
            """A driver method called; the error queue must be empty after it."""
            call()
            errs = errors(gen)
            if errs:
                failures.append(f"{label}: errors {errs}")

        # arb_file, with the methods that feed it: data_volatile_clear, data_arb (DAC and float).
        method("data_volatile_clear", gen.data_volatile_clear)
        method("data_arb DAC",
               lambda: gen.data_arb("PYRAMP", range(-10000, 10000, 2000), data_format="DAC"))
        method("data_arb float", lambda: gen.data_arb(
            "PYFLOAT", [-1.0, -0.5, 0.0, 0.5, 1.0, 0.5, 0.0, -0.5], data_format="float"))
        passed = 0
        for name in ("PYRAMP", "PYFLOAT"):
            gen.arb_file = name
            got = unquote(gen.arb_file)
            if got == name and not errors(gen):
                passed += 1
            else:
                failures.append(f"arb_file = {name!r}: read {got!r}")
        table.add("arb_file", 2, passed, "(read back quoted, as the instrument answers)")

        # The remaining methods: a bus-triggered burst, beep, and Instrument's clear / reset.
        gen.write("BURS:NCYC 2;STAT ON;:TRIG:SOUR BUS;:OUTP ON")
        method("trigger", gen.trigger)
        method("wait_for_trigger", lambda: gen.wait_for_trigger(timeout=5))
        method("beep", gen.beep)
        gen.write("BURS:STAT OFF;:OUTP OFF")
        gen.write("BOGUS:HEADER")  # one error queued: clear() (*CLS) must empty the queue
        method("clear", gen.clear)
        gen.write("FREQ 2500")
        method("reset", gen.reset)  # *RST: the default 1 kHz again
        if not close(gen.frequency, 1000.0):
            failures.append(f"reset: frequency {gen.frequency!r} after *RST, want 1000")
        final = gen.ask("SYST:ERR?").strip()
        if final != NO_ERROR:
            failures.append(f"error queue after the methods: {final!r}")

        # Out of range and conflicting sets queue the 33500's error codes.
        expect = [
            ("FREQ 40 MHZ", "-222"),               # above 30 MHz
            ("FUNC:PULS:TRAN 5E-6", "-222"),       # edge time above 1 us
            ("BURS:NCYC 0", "-222"),               # count below 1
            ("FUNC:ARB:SRAT 250E6", "-222"),       # above 160 MSa/s
            ("VOLT 9;:VOLT:OFFS 3", "-221"),       # 4.5 V + 3 V exceed 5 V into 50 ohm
            ("VOLT:HIGH -2;:VOLT:LOW 0", "-221"),  # high level below low level
            ("OUTP:LOAD INF;:VOLT:UNIT DBM", "-221"),
            ("FUNC:PULS:WIDT 2E-3", "-221"),       # wider than the 1 ms period
            ("BURS:NCYC 50;INT:PER 1E-3", "-221"),  # 50 cycles at 1 kHz need 50 ms
            ("FUNC:PULS:WIDTH:FOO 1", "-113"),
            ("BURS:MODE SOMETIMES", "-224"),
        ]
        passed = 0
        for command, code in expect:
            gen.write("*RST;*CLS")
            gen.write(command)
            got = gen.ask("SYST:ERR?").strip()
            if got.startswith(code + ","):
                passed += 1
            else:
                failures.append(f"{command!r}: got {got!r}, want {code}")
        print(f"error codes: {passed} of {len(expect)} as the 33500 reports them")
        gen.write("*RST;*CLS")
        final = gen.ask("SYST:ERR?").strip()
        if final != NO_ERROR:
            failures.append(f"final error queue: {final!r}")
        adapter.connection.close()
    finally:
        server.stdin.close()
        server.wait(timeout=10)

    all_ok = table.print()
    for f in failures:
        print("FAIL", f)
    if failures or not all_ok:
        sys.exit(1)
    print("PASS")


if __name__ == "__main__":
    main()
