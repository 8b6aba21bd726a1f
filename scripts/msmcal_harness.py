"""What the scripts that drive msmcal processes and the CLI tests share (scripts/fault_campaign.py,
tests/app/cli_testlib.py): one SCPI query on a new connection (the mock generators' state as any
client sees it), a process's output lines collected by a thread to wait on (a line, never a
sleep), a bounded wait for a process to end through a pidfd, and a program on a pty.

Standard library only (/usr/bin/python3). Import it from scripts/ directly, from elsewhere with
scripts/ put on sys.path (as tests/app/cli_testlib.py does).
"""

import os
import pty
import re
import select
import socket
import threading
import time


def scpi(port, text, timeout_s=5.0):
    """`text` (ending in a query) on a new connection to 127.0.0.1:`port`; the reply line without
    its terminator ("" when the peer closed first). A one-connection-at-a-time mock serves this
    only once every other connection is closed. Raises OSError when it cannot connect or times
    out."""
    with socket.create_connection(("127.0.0.1", port), timeout=timeout_s) as s:
        s.sendall((text + "\n").encode())
        reply = b""
        while not reply.endswith(b"\n"):
            chunk = s.recv(4096)
            if not chunk:
                break
            reply += chunk
        return reply.decode(errors="replace").strip()


def wait_pid(pid, deadline_s):
    """Waits up to deadline_s for process `pid` to end and reaps it: its wait status. None when
    it is still running at the deadline, is gone already, or is not ours to reap (a process
    reparented to a child subreaper is)."""
    try:
        fd = os.pidfd_open(pid)
    except OSError:
        return None
    try:
        if not select.select([fd], [], [], deadline_s)[0]:
            return None
        try:
            return os.waitpid(pid, 0)[1]
        except ChildProcessError:
            return None
    finally:
        os.close(fd)


class Lines:
    """The lines of a text-mode pipe (`proc.stdout`, stderr merged into it by the caller), read
    by a thread from the start so the process never blocks on a full pipe. Each line is echoed
    to stdout prefixed by `tag` (when given) and written to the file `log` (when given).
    wait_for blocks on them until a pattern shows up; thread safe."""

    def __init__(self, proc, tag=None, log=None):
        self.proc, self.tag, self.log = proc, tag, log
        self.lines, self.done = [], False
        self.cv = threading.Condition()
        self.reader = threading.Thread(target=self._read, daemon=True)
        self.reader.start()

    def _read(self):
        for line in self.proc.stdout:
            line = line.rstrip("\n")
            if self.tag is not None:
                print("%s| %s" % (self.tag, line), flush=True)
            if self.log is not None:
                self.log.write(line + "\n")
                self.log.flush()
            self.append(line)
        with self.cv:
            self.done = True
            self.cv.notify_all()

    def append(self, line):
        """Adds a line of the caller's (a note next to the process's own lines)."""
        with self.cv:
            self.lines.append(line)
            self.cv.notify_all()

    def wait_for(self, pattern, deadline_s):
        """The first line's match of `pattern`, waiting up to deadline_s; None when none came
        (the deadline passed or the pipe closed)."""
        rx = re.compile(pattern)
        end = time.monotonic() + deadline_s
        with self.cv:
            while True:
                for l in self.lines:
                    m = rx.search(l)
                    if m:
                        return m
                left = end - time.monotonic()
                if self.done or left <= 0:
                    return None
                self.cv.wait(left)

    def wait_done(self, deadline_s):
        """Waits up to deadline_s for the pipe to close (every line read); whether it did."""
        with self.cv:
            return self.cv.wait_for(lambda: self.done, deadline_s)

    def text(self):
        with self.cv:
            return "\n".join(self.lines)


class PtyChild:
    """A program on a pseudo-terminal (pty.fork), read with select() and deadlines; `out` is all
    it printed ("\r\n" folded to "\n"), `eof` set once it closed the terminal. Subclasses add
    the reading a test needs (up to a marker, the next prompt)."""

    def __init__(self, argv):
        self.pid, self.fd = pty.fork()
        if self.pid == 0:
            try:
                os.execv(argv[0], argv)
            finally:
                os._exit(127)
        self.out = ""
        self.pos = 0  # start of the text not yet consumed
        self.eof = False

    def _read(self, deadline):
        """Reads what is there before `deadline`; False at the deadline or at the end."""
        left = deadline - time.monotonic()
        if left <= 0:
            return False
        ready, _, _ = select.select([self.fd], [], [], left)
        if not ready:
            return False
        try:
            data = os.read(self.fd, 65536)
        except OSError:  # EIO: the child closed the terminal
            data = b""
        if not data:
            self.eof = True
            return False
        self.out += data.decode("utf-8", "replace").replace("\r\n", "\n")
        return True
