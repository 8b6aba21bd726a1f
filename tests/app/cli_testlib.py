"""What the CLI tests in tests/app share: fail(), one SCPI query on a new connection (the mock
generators' outputs as a client sees them), and a process's output lines collected by a thread
to wait on (a line, not a sleep)."""

import re
import socket
import sys
import threading
import time


def fail(msg):
    print("FAIL: " + msg, flush=True)
    sys.exit(1)


def scpi(port, text):
    """`text` (ending in a query) on a new connection; the reply line."""
    with socket.create_connection(("127.0.0.1", port), timeout=5) as s:
        s.sendall((text + "\n").encode())
        reply = b""
        while not reply.endswith(b"\n"):
            chunk = s.recv(4096)
            if not chunk:
                break
            reply += chunk
        return reply.decode().strip()


class Lines:
    """A process's stdout + stderr lines, collected by a thread; wait_for blocks on them."""

    def __init__(self, proc, tag):
        self.proc, self.tag, self.lines, self.done = proc, tag, [], False
        self.cv = threading.Condition()
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self):
        for line in self.proc.stdout:
            print("%s| %s" % (self.tag, line.rstrip("\n")), flush=True)
            with self.cv:
                self.lines.append(line.rstrip("\n"))
                self.cv.notify_all()
        with self.cv:
            self.done = True
            self.cv.notify_all()

    def wait_for(self, pattern, deadline_s):
        """The first line's match of `pattern`, waiting up to deadline_s; None when none came."""
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
        with self.cv:
            self.cv.wait_for(lambda: self.done, deadline_s)

    def text(self):
        with self.cv:
            return "\n".join(self.lines)
