#!/usr/bin/python3
"""Conformance of the mock 33520B against clients we did not write.

usage: conformance.py pyvisa|lxi|vxi11-pyvisa|vxi11-lxi|vxi11-rpc SERVER_EXE

Starts SERVER_EXE (prints "listening on 127.0.0.1:P", serves until its stdin closes), then checks
identity, the error queue, a binary arbitrary-waveform upload (both byte orders, payload bytes
equal to '\\n') and the read-back of the state, with Debian's python3-pyvisa + pyvisa-py, or with
lxi-tools' `lxi scpi -r`. Exits non-zero with a message on the first mismatch.

The vxi11-* modes start the server with its VXI-11 channels and the portmapper on port 111 (run
them as root in `unshare -rn`: tests/drivers/camera/netns_exec.sh) and go through the portmapper
as lab tools do: pyvisa-py's `TCPIP::127.0.0.1::INSTR` (vxi11-pyvisa: the same checks, plus state
written over VXI-11 read back on the raw socket), lxi-tools' default VXI-11 path `lxi scpi -a`
(vxi11-lxi), and hand-built RPC records (vxi11-rpc: an unknown link id answers error 4, a
malformed call GARBAGE_ARGS, an unknown procedure PROC_UNAVAIL, and the server still serves).
"""
import socket
import struct
import subprocess
import sys

IDN = "Keysight Technologies,33520B,MY00000042,4.00-1.19-2.00-58-00"


def check(label, got, want):
    if got != want:
        sys.exit(f"FAIL {label}: got {got!r}, want {want!r}")
    print(f"ok   {label}: {got!r}")


def start_server(exe, vxi11=False):
    args = [exe, IDN] + (["--vxi11", "111"] if vxi11 else [])
    server = subprocess.Popen(args, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    line = server.stdout.readline().strip()
    if not line.startswith("listening on 127.0.0.1:"):
        server.kill()
        sys.exit(f"FAIL server start: {line!r}")
    port = int(line.rsplit(":", 1)[1])
    if vxi11:
        line = server.stdout.readline().strip()
        if not line.endswith("portmapper 127.0.0.1:111"):
            server.kill()
            sys.exit(f"FAIL VXI-11 start (run in unshare -rn for port 111): {line!r}")
    return server, port


def run_pyvisa(port, resource=None):
    import pyvisa

    rm = pyvisa.ResourceManager("@py")
    # pyvisa's default write termination for SOCKET resources is "\r\n": the mock must ignore CR.
    inst = rm.open_resource(resource or f"TCPIP0::127.0.0.1::{port}::SOCKET",
                            read_termination="\n", timeout=5000)
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


def run_vxi11_pyvisa(port):
    # The same checks through the portmapper and the core channel, both resource spellings.
    run_pyvisa(port, "TCPIP::127.0.0.1::INSTR")
    import pyvisa

    rm = pyvisa.ResourceManager("@py")
    inst = rm.open_resource("TCPIP0::127.0.0.1::inst0::INSTR", timeout=5000)
    check("inst0 *IDN?", inst.query("*IDN?").rstrip("\n"), IDN)
    # One instrument, both wires: set over VXI-11, read back on the raw socket and vice versa.
    inst.write("SOUR1:FREQ 4321;:SOUR1:VOLT 0.75")
    raw = rm.open_resource(f"TCPIP0::127.0.0.1::{port}::SOCKET", read_termination="\n",
                           timeout=5000)
    check("raw sees VXI-11 state", raw.query("SOUR1:FREQ?;VOLT?"),
          "+4.3210000000000E+03;+7.5000000000000E-01")
    raw.write("SOUR2:FREQ 777")
    # The two wires are two connections: the raw write has no reply, so *OPC? on the same socket
    # is what says it was executed before the VXI-11 query.
    check("raw *OPC?", raw.query("*OPC?"), "1")
    check("VXI-11 sees raw state", inst.query("SOUR2:FREQ?").rstrip("\n"),
          "+7.7700000000000E+02")
    # A reply larger than one device_read: pyvisa-py reads it in chunks until END.
    values = list(range(-2000, 2000))
    inst.write("FORM:BORD SWAP")
    inst.write_binary_values("SOUR1:DATA:ARB:DAC BIG,", values, datatype="h", is_big_endian=False)
    check("big upload", inst.query("SYST:ERR?").rstrip("\n"), '+0,"No error"')
    check("big points", inst.query("SOUR1:DATA:ATTR:POIN? BIG").rstrip("\n"), f"+{len(values)}")
    inst.clear()  # device_clear
    check("after device_clear", inst.query("*IDN?").rstrip("\n"), IDN)
    check("readstb", inst.read_stb(), 0)
    inst.assert_trigger()  # device_trigger
    check("after trigger", inst.query("SYST:ERR?").rstrip("\n"), '+0,"No error"')
    raw.close()
    inst.close()
    rm.close()


def run_vxi11_lxi(port):
    out = subprocess.run(["lxi", "scpi", "-a", "127.0.0.1", "-t", "5", "*IDN?"],
                         capture_output=True, text=True, timeout=30)
    check("lxi VXI-11 *IDN?", (out.returncode, out.stdout.strip()), (0, IDN))
    out = subprocess.run(["lxi", "scpi", "-a", "127.0.0.1", "-t", "5", "SOUR1:FREQ 2500"],
                         capture_output=True, text=True, timeout=30)
    check("lxi VXI-11 write", out.returncode, 0)
    out = subprocess.run(["lxi", "scpi", "-a", "127.0.0.1", "-t", "5", "SOUR1:FREQ?"],
                         capture_output=True, text=True, timeout=30)
    check("lxi VXI-11 query", (out.returncode, out.stdout.strip()), (0, "+2.5000000000000E+03"))


def xdr(*words):
    return b"".join(struct.pack(">I", w & 0xFFFFFFFF) for w in words)


def rpc_call(sock, xid, prog, vers, proc, args):
    record = xdr(xid, 0, 2, prog, vers, proc, 0, 0, 0, 0) + args
    sock.sendall(struct.pack(">I", 0x80000000 | len(record)) + record)
    return recv_record(sock)


def recv_record(sock):
    def exactly(n):
        data = b""
        while len(data) < n:
            chunk = sock.recv(n - len(data))
            if not chunk:
                sys.exit("FAIL connection closed by the server")
            data += chunk
        return data

    header = struct.unpack(">I", exactly(4))[0]
    return exactly(header & 0x7FFFFFFF)


def run_vxi11_rpc(port):
    with socket.create_connection(("127.0.0.1", 111), timeout=5) as pm:
        reply = rpc_call(pm, 7, 100000, 2, 3, xdr(0x0607AF, 1, 6, 0))
        check("GETPORT reply header", reply[:24], xdr(7, 1, 0, 0, 0, 0))
        core = struct.unpack(">I", reply[24:28])[0]
        check("NULL", rpc_call(pm, 8, 100000, 2, 0, b""), xdr(8, 1, 0, 0, 0, 0))
    ok = xdr(1, 0, 0, 0, 0)  # REPLY, MSG_ACCEPTED, AUTH_NONE (empty), SUCCESS
    with socket.create_connection(("127.0.0.1", core), timeout=5) as s:
        # device_write on an unknown link: error 4, 0 bytes.
        check("unknown link write", rpc_call(s, 21, 0x0607AF, 1, 11, xdr(999, 1000, 0, 8, 0)),
              xdr(21) + ok + xdr(4, 0))
        check("unknown link read", rpc_call(s, 22, 0x0607AF, 1, 12, xdr(999, 100, 0, 0, 0, 0)),
              xdr(22) + ok + xdr(4, 0, 0))
        # Arguments cut short: GARBAGE_ARGS (accept_stat 4).
        check("short args", rpc_call(s, 23, 0x0607AF, 1, 11, xdr(1, 2)), xdr(23, 1, 0, 0, 0, 4))
        check("unknown proc", rpc_call(s, 24, 0x0607AF, 1, 99, b""), xdr(24, 1, 0, 0, 0, 3))
        check("wrong version", rpc_call(s, 25, 0x0607AF, 7, 10, b""),
              xdr(25, 1, 0, 0, 0, 2, 1, 1))
        # A record too short for a call header but with an xid: GARBAGE_ARGS.
        s.sendall(struct.pack(">I", 0x80000006) + b"\0\0\0\x1a\0\0")
        check("malformed call", recv_record(s), xdr(26, 1, 0, 0, 0, 4))
        # The connection and the server still serve: create_link inst0, *IDN?.
        reply = rpc_call(s, 30, 0x0607AF, 1, 10, xdr(5, 0, 0, 5) + b"inst0\0\0\0")
        check("create_link", reply[:28], xdr(30) + ok + xdr(0))
        link = struct.unpack(">i", reply[28:32])[0]
        check("write *IDN?", rpc_call(s, 31, 0x0607AF, 1, 11, xdr(link, 1000, 0, 8, 5) +
                                      b"*IDN?\0\0\0"), xdr(31) + ok + xdr(0, 5))
        want = (IDN + "\n").encode()
        pad = b"\0" * (-len(want) % 4)
        check("read", rpc_call(s, 32, 0x0607AF, 1, 12, xdr(link, 4096, 1000, 0, 0, 0)),
              xdr(32) + ok + xdr(0, 4, len(want)) + want + pad)
        check("destroy_link", rpc_call(s, 33, 0x0607AF, 1, 23, xdr(link)), xdr(33) + ok + xdr(0))
        check("destroyed", rpc_call(s, 34, 0x0607AF, 1, 23, xdr(link)), xdr(34) + ok + xdr(4))


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


MODES = {"pyvisa": run_pyvisa, "lxi": run_lxi, "vxi11-pyvisa": run_vxi11_pyvisa,
         "vxi11-lxi": run_vxi11_lxi, "vxi11-rpc": run_vxi11_rpc}


def main():
    if len(sys.argv) != 3 or sys.argv[1] not in MODES:
        sys.exit(__doc__)
    server, port = start_server(sys.argv[2], vxi11=sys.argv[1].startswith("vxi11"))
    try:
        MODES[sys.argv[1]](port)
    finally:
        server.stdin.close()
        server.wait(timeout=10)
    print("PASS")


if __name__ == "__main__":
    main()
