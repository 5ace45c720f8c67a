#!/usr/bin/env bash
# tools/jack/reclaim_registry.py against a real jackd: a server killed by SIGKILL leaves its registry
# slot behind (JACK frees it only for a server of the same name); the script must find it dead and
# free it through jackd itself, and leave a live server's slot alone.
set -u
PY=$1; SCRIPT=$2
DEAD="locus_regtest_dead_$$"; LIVE="locus_regtest_live_$$"
LIVE_PID=""
cleanup() { [ -n "$LIVE_PID" ] && kill "$LIVE_PID" 2> /dev/null && wait "$LIVE_PID" 2> /dev/null; }
trap cleanup EXIT
fail() { echo "FAIL $*"; "$PY" "$SCRIPT" --list; exit 1; }
wait_registered() {  # name -> 0 once the registry lists it
  for _ in $(seq 100); do "$PY" "$SCRIPT" --list | grep -q ":$1:\$" && return 0; sleep 0.1; done
  return 1
}

jackd -n "$DEAD" -r -d dummy -r 44100 -p 1024 > /dev/null 2>&1 &
DEAD_PID=$!
wait_registered "$DEAD" || fail "jackd $DEAD never registered"
kill -9 "$DEAD_PID"; wait "$DEAD_PID" 2> /dev/null
"$PY" "$SCRIPT" --list | grep -q "pid $DEAD_PID dead jack-$(id -u):$DEAD:\$" || fail "the killed server's slot is not listed as dead"
echo "ok   SIGKILLed jackd '$DEAD' left its slot behind, listed as dead"

jackd -n "$LIVE" -r -d dummy -r 44100 -p 1024 > /dev/null 2>&1 &
LIVE_PID=$!
wait_registered "$LIVE" || fail "jackd $LIVE never registered"

"$PY" "$SCRIPT" --prefix locus_regtest_ || fail "reclaim_registry.py exited $?"
"$PY" "$SCRIPT" --list | grep -q ":$DEAD:\$" && fail "the dead server's slot is still taken"
echo "ok   the dead server's slot was reclaimed"
"$PY" "$SCRIPT" --list | grep -q "pid $LIVE_PID alive jack-$(id -u):$LIVE:\$" || fail "the live server's slot was touched"
kill -0 "$LIVE_PID" || fail "the live server died"
echo "ok   the live server and its slot were left alone"
ls /dev/shm | grep -q "_${DEAD}_" && fail "files of the dead server remain in /dev/shm: $(ls /dev/shm | grep "_${DEAD}_")"
echo "ok   no file of the dead server left in /dev/shm"
