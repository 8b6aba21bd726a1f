#!/usr/bin/python3
"""Conformance of the mock 33520B against clients we did not write.

usage: conformance.py pyvisa|lxi SERVER_EXE

Starts SERVER_EXE (prints "listening on 127.0.0.1:P", serves until its stdin closes), then checks
identity, the error queue, a binary arbitrary-waveform upload (both byte orders, payload bytes
equal to '\\n') and the read-back of the state, with Debian's python3-pyvisa + pyvisa-py, or with
lxi-tools' `lxi scpi -r`. Exits non-zero with a message on the first mismatch.
"""
import subprocess
import sys

IDN = "Keysight Technologies,33520B,MY00000042,4.00-1.19-2.00-58-00"


def check(label, got, want):
    if got != want:
        sys.exit(f"FAIL {label}: got {got!r}, want {want!r}")
    print(f"ok   {label}: {got!r}")


def start_server(exe):
    server = subprocess.Popen([exe, IDN], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    line = server.stdout.readline().strip()
    if not line.startswith("listening on 127.0.0.1:"):
        server.kill()
        sys.exit(f"FAIL server start: {line!r}")
    return server, int(line.rsplit(":", 1)[1])


def run_pyvisa(port):
    import pyvisa

    rm = pyvisa.ResourceManager("@py")
    # pyvisa's default write termination for SOCKET resources is "\r\n": the mock must ignore CR.
    inst = rm.open_resource(f"TCPIP0::127.0.0.1::{port}::SOCKET", read_termination="\n",
                            timeout=5000)
    check("*IDN?", inst.query("*IDN?"), IDN)
    check("empty queue", inst.query("SYST:ERR?"), '+0,"No error"')
    inst.write("BOGUS:HEADER 1")
    inst.write("SOUR1:FREQ 1 FOO")
    check("error 1", inst.query("SYST:ERR?"), '-113,"Undefined header"')
    check("error 2", inst.query("SYSTem:ERRor:NEXT?"), '-131,"Invalid suffix"')
    check("drained", inst.query("SYST:ERR?"), '+0,"No error"')
    check("compound", inst.query("SOUR2:FREQ 2.5 KHZ;VOLT 250 MV;:SOUR2:FREQ?;VOLT?"),
          "+2.5000000000000E+03;+2.5000000000000E-01")
    values = [-32767, 0, 2570, 32767, 10, 13, 59, 35, 2570, -1, 1, 0]  # 2570 = 0x0A0A
    for order, big in (("SWAP", False), ("NORM", True)):
        name = "PY" + order
        inst.write(f"FORM:BORD {order}")
        inst.write_binary_values(f"SOUR1:DATA:ARB:DAC {name},", values, datatype="h",
                                 is_big_endian=big)
        check(f"upload {order}", inst.query("SYST:ERR?"), '+0,"No error"')
        check(f"points {order}", inst.query(f"SOUR1:DATA:ATTR:POIN? {name}"), f"+{len(values)}")
    inst.write("SOUR1:FUNC:ARB PYSWAP;:SOUR1:FUNC ARB;:SOUR1:FUNC:ARB:SRAT 100 KHZ")
    check("FUNC?", inst.query("SOUR1:FUNC?"), "ARB")
    check("FUNC:ARB?", inst.query("SOUR1:FUNC:ARB?"), '"PYSWAP"')
    check("SRAT", inst.query_ascii_values("SOUR1:FUNC:ARB:SRAT?"), [100000.0])
    check("catalog", inst.query("SOUR1:DATA:VOL:CAT?"), '"PYNORM","PYSWAP"')
    inst.write("SOUR1:DATA:ARB:DAC BAD,#13abc")  # an odd byte count cannot hold int16 samples
    check("bad block", inst.query("SYST:ERR?"), '-161,"Invalid block data"')
    inst.write("OUTP1 ON")
    check("OUTP1?", inst.query("OUTP1?"), "1")
    inst.write("*RST")
    check("*RST", inst.query("OUTP1?;:SOUR1:FUNC?"), "0;SIN")
    inst.close()
    rm.close()


def lxi(port, command):
    out = subprocess.run(["lxi", "scpi", "-r", "-a", "127.0.0.1", "-p", str(port), "-t", "5",
                          command], capture_output=True, text=True, timeout=30)
    if out.returncode != 0:
        sys.exit(f"FAIL lxi {command!r}: exit {out.returncode}: {out.stderr.strip()}")
    return out.stdout.strip()


def run_lxi(port):
    check("*IDN?", lxi(port, "*IDN?"), IDN)
    check("empty queue", lxi(port, "SYST:ERR?"), '+0,"No error"')
    lxi(port, "BOGUS:HEADER 1")
    check("error", lxi(port, "SYST:ERR?"), '-113,"Undefined header"')
    # argv cannot carry NUL or non-UTF-8 bytes: a 16-byte payload of ASCII, with ';' ',' '"'
    # and '\n' inside the block.
    lxi(port, 'FORM:BORD NORM;:SOUR2:DATA:ARB:DAC LXI,#216AB;C,D"E\nFGHIJKL')
    check("upload", lxi(port, "SYST:ERR?"), '+0,"No error"')
    check("points", lxi(port, "SOUR2:DATA:ATTR:POIN? LXI"), "+8")
    lxi(port, "SOUR2:FUNC:ARB LXI;:SOUR2:FUNC ARB")
    check("state", lxi(port, "SOUR2:FUNC?;:SOUR2:FUNC:ARB?"), 'ARB;"LXI"')


def main():
    if len(sys.argv) != 3 or sys.argv[1] not in ("pyvisa", "lxi"):
        sys.exit(__doc__)
    server, port = start_server(sys.argv[2])
    try:
        (run_pyvisa if sys.argv[1] == "pyvisa" else run_lxi)(port)
    finally:
        server.stdin.close()
        server.wait(timeout=10)
    print("PASS")


if __name__ == "__main__":
    main()
