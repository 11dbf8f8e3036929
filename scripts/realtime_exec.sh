#!/bin/sh
# realtime_exec.sh PRIORITY COMMAND [ARGS...]: runs COMMAND under SCHED_FIFO at PRIORITY (1-99) where this user
# may (root, CAP_SYS_NICE, or an rtprio limit: ulimit -r), and as it is otherwise or when PRIORITY is 0.
# clod_haptics.launch starts the nodelet manager through it: roscpp's threads there (the one that reads the pose
# socket, the publishers) then cannot be preempted by ordinary processes while they hold a lock the detector's
# pose thread waits for. The detector's level worker puts itself back on the default scheduler (nice 10).
prio=$1
shift
case "$prio" in
  '' | *[!0-9]*) echo "realtime_exec.sh: the priority must be a number 0-99, not '$prio'" >&2; exit 2 ;;
esac
if [ "$prio" -gt 0 ] && chrt -f "$prio" true 2>/dev/null; then
  exec chrt -f "$prio" "$@"
fi
exec "$@"
