#!/bin/sh
# Runs a test in its own user + network namespace with only loopback up, so that GigE Vision
# servers (fixed port 3956) of parallel tests never collide and no broadcast leaves the machine.
exec unshare -rn sh -c 'ip link set lo up && exec "$0" "$@"' "$@"
