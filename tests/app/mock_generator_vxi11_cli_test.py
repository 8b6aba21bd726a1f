#!/usr/bin/python3
"""`msmcal mock generator --vxi11` through the msmcal binary, as a lab tool meets it.

Runs in its own user + network namespace (tests/drivers/camera/netns_exec.sh), so the mock's
portmapper can bind port 111. For each of SIGTERM and SIGINT: starts `msmcal mock generator
--port 0 --vxi11 --idn ...`, waits for its two announcement lines (the raw SCPI port; the VXI-11
core and abort channels and the portmapper on 127.0.0.1:111), then

- talks VXI-11 to it with pyvisa-py (`TCPIP::127.0.0.1::INSTR`: portmapper GETPORT, create_link,
  device_write / device_read) and with lxi-tools (`lxi scpi -a`, its default VXI-11 path): the
  *IDN? transcript must be exactly the identity given, the error queue empty;
- checks that both wires reach one instrument (a setting written over VXI-11 read back on the raw
  socket, and the reverse);
- stops it with the signal (with the SIGINT run's VXI-11 link still open: a client that never
  said destroy_link must not hold the mock up) and requires a clean shutdown: exit status 0
  within 5 s, its summary line counting exactly the raw connections and messages this test sent,
  nothing on stderr, and every port it served closed.

Also: `--portmapper-port` without `--vxi11` is refused naming the option.

usage: mock_generator_vxi11_cli_test.py MSMCAL
"""
import re
import signal
import socket
import subprocess
import sys

from cli_testlib import fail, scpi  # tests/app/cli_testlib.py

IDN = "Keysight Technologies,33520B,MY00VXI11T,4.00-1.19-2.00-58-00"
NO_ERROR = '+0,"No error"'


def check(label, got, want):
    if got != want:
        fail("%s: got %r, want %r" % (label, got, want))
    print("ok   %s: %r" % (label, got), flush=True)


def start(msmcal):
    proc = subprocess.Popen([msmcal, "mock", "generator", "--port", "0", "--vxi11", "--idn", IDN],
                            stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    first = proc.stdout.readline().strip()
    second = proc.stdout.readline().strip()
    m1 = re.fullmatch(r"listening on 127\.0\.0\.1:(\d+)", first)
    m2 = re.fullmatch(r"VXI-11 core channel on 127\.0\.0\.1:(\d+), abort channel on "
                      r"127\.0\.0\.1:(\d+), portmapper on 127\.0\.0\.1:111", second)
    if not m1 or not m2:
        proc.kill()
        fail("announcement: %r, %r; stderr %r" % (first, second, proc.stderr.read()))
    return proc, int(m1.group(1)), int(m2.group(1)), int(m2.group(2))


def closed(port):
    try:
        socket.create_connection(("127.0.0.1", port), timeout=2).close()
        return False
    except ConnectionRefusedError:
        return True


def run(msmcal, sig):
    import pyvisa

    name = signal.Signals(sig).name
    proc, raw_port, core_port, abort_port = start(msmcal)
    rm = pyvisa.ResourceManager("@py")
    inst = rm.open_resource("TCPIP::127.0.0.1::INSTR", timeout=5000)
    transcript = []

    def query(text):
        reply = inst.query(text).rstrip("\n")
        transcript.append((text, reply))
        return reply

    check(name + " VXI-11 *IDN?", query("*IDN?"), IDN)
    check(name + " VXI-11 SYST:ERR?", query("SYST:ERR?"), NO_ERROR)
    inst.write("SOUR1:FREQ 1234.5;:SOUR1:VOLT 0.5")
    check(name + " VXI-11 transcript", transcript,
          [("*IDN?", IDN), ("SYST:ERR?", NO_ERROR)])
    # One instrument, both wires (each scpi() is one raw connection, one message).
    check(name + " raw sees the VXI-11 setting", scpi(raw_port, "SOUR1:FREQ?;VOLT?"),
          "+1.2345000000000E+03;+5.0000000000000E-01")
    check(name + " raw write acknowledged", scpi(raw_port, "SOUR2:FREQ 777;*OPC?"), "1")
    check(name + " VXI-11 sees the raw setting", query("SOUR2:FREQ?"), "+7.7700000000000E+02")
    lxi = subprocess.run(["lxi", "scpi", "-a", "127.0.0.1", "-t", "5", "*IDN?"],
                         capture_output=True, text=True, timeout=30)
    check(name + " lxi VXI-11 *IDN?", (lxi.returncode, lxi.stdout.strip()), (0, IDN))
    check(name + " error queue at the end", query("SYST:ERR?"), NO_ERROR)
    if sig == signal.SIGTERM:
        inst.close()  # destroy_link; the SIGINT run leaves its link open
        rm.close()

    proc.send_signal(sig)
    try:
        out, err = proc.communicate(timeout=5)
    except subprocess.TimeoutExpired:
        proc.kill()
        fail("%s: the mock did not exit within 5 s" % name)
    check(name + " exit status", proc.returncode, 0)
    check(name + " stderr", err, "")
    # The raw wire saw exactly this test's two connections and two program messages.
    check(name + " summary", out.strip().splitlines()[-1],
          "generator: 2 connection(s), 2 message(s), 0 fault(s) applied, "
          "0 connection(s) turned away")
    for label, port in (("raw", raw_port), ("core", core_port), ("abort", abort_port),
                        ("portmapper", 111)):
        check("%s %s port closed" % (name, label), closed(port), True)
    if sig != signal.SIGTERM:
        try:
            rm.close()
        except Exception:  # the link's socket is gone with the server: nothing to tell it
            pass


def main():
    if len(sys.argv) != 2:
        fail(__doc__)
    msmcal = sys.argv[1]
    r = subprocess.run([msmcal, "mock", "generator", "--port", "0", "--portmapper-port", "1111"],
                       capture_output=True, text=True, timeout=30)
    check("--portmapper-port without --vxi11 refused", r.returncode != 0, True)
    if "--portmapper-port need --vxi11" not in r.stderr + r.stdout:
        fail("refusal does not name the option: %r" % (r.stderr + r.stdout))
    for sig in (signal.SIGTERM, signal.SIGINT):
        run(msmcal, sig)
    print("PASS", flush=True)


if __name__ == "__main__":
    main()
