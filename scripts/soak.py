#!/usr/bin/python3
"""Soak of the detector as users run it: the shipped launch/clod_haptics.launch with its defaults.

Starts launch/clod_haptics.launch (sphere_builder, the nodelet manager `clod_manager` and the detector
nodelet, every queue size and policy at its default) on its own ROS master, then for --duration seconds
(default 600):
  * streams stylus poses at 1 kHz (--rate) that slide over the surface and press into it (the pointer
    centre goes from 3 r outside to 2 r inside along the surface normal, about 1.4 Hz), each with a unique
    stamp so every contact is matched to its pose;
  * subscribes to ~markers (raw bytes, counted: the subscription alone makes the nodelet build them);
  * reconfigures clustering_distance every --reconfigure-period seconds, cycling through --distances,
    and every fourth time also the pointer radius (--radii): in this process (--reconfigure-with client)
    or, as a user at a shell does, by starting `dynparam set` each time (--reconfigure-with dynparam: a
    Python process started every period, each one competing with the pose path for the CPU);
  * samples the manager's RSS (/proc/<pid>/status) every 5 s, printing it at the start, every 30 s
    and at the end;
  * records every WARN/ERROR/FATAL published on /rosout (and ERROR/died lines of the launch log).
At the end it prints poses sent, contacts received, unanswered poses, the detector's loss counters (gaps in
the pose stream, stale poses skipped) and the gaps in the answers' header.seq, RSS start/end/max, warnings
(expected and unexpected), percentiles of the detection time the contacts carry and of the detector's own
pose path (~status: roscpp's receipt of a pose to its answer published, queue wait included).

Exit status 1 when a pose went unanswered or was counted lost or skipped, the RSS grew by more than --rss-bound-mib after the warm-up
(--warmup seconds, at least one full cycle of distances: every level has been built and cached once),
an unexpected warning or error was logged, no level swap happened, or the launch died.

The RSS bound: 32 MiB of growth of the RSS floor after the warm-up, the lowest RSS over the last third of the
samples against the lowest over the first third. Once every level of the cycle has been loaded, the manager holds
the levels in use plus, for a moment, the one being built (a grid's temporaries), so the RSS rises while a level
is built and comes back when glibc returns the memory: a 10-minute run on refined_elephant swung between 111 and
155 MiB and ended at its floor. A leak raises the floor; a build in flight only a peak, which is reported, not
bounded. The floors of the two thirds are about two thirds of the run apart, so 32 MiB is exceeded by a leak of
about 90 bytes per pose over 540,000 poses, or of about 90 KiB per reconfigure over 540 reconfigures. The report
also prints the growth over the second half of the run after the warm-up.

  scripts/soak.py [--duration 600] [--mesh FILE --scale S]     # after sourcing devel/setup.bash
  make soak SOAK_SECONDS=600

--attach runs against nodes already started (test/rostest/soak_short.test includes clod_haptics.launch).
"""
import argparse
import math
import os
import re
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
import xmlrpc.client

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
SHARED = os.environ.get("CLOD_SHARED_DIR", os.path.normpath(os.path.join(ROOT, "..", "shared")))
DEFAULT_MESH = os.path.join(SHARED, "data", "meshes", "mannequin-devil.off")
FALLBACK_MESH = os.path.join(ROOT, "data", "meshes", "torus.obj")

# WARN and above that a soak may log, with the reason. Anything else fails the soak.
EXPECTED_WARNINGS = [
    # None so far: the soak sends only valid poses and in-range settings, and sphere_builder is up.
]

RSS_SAMPLE_PERIOD = 5.0
RSS_PRINT_PERIOD = 30.0


# ------------------------------------------------------------------------------------------------
# Mesh and trajectory.

def resolve_mesh(uri):
    if uri.startswith("package://"):
        import rospkg
        pkg, rel = uri[len("package://"):].split("/", 1)
        return os.path.join(rospkg.RosPack().get_path(pkg), rel)
    return uri


def load_mesh(path):
    """Vertices (n, 3) and triangles (m, 3) of an OFF or OBJ file (polygons fanned)."""
    vertices, faces = [], []
    with open(path) as f:
        if path.lower().endswith(".off"):
            tokens = f.read().split()
            if tokens[0] != "OFF":
                raise ValueError("%s: not an OFF file" % path)
            nv, nf = int(tokens[1]), int(tokens[2])
            pos = 4
            for _ in range(nv):
                vertices.append([float(t) for t in tokens[pos:pos + 3]])
                pos += 3
            for _ in range(nf):
                k = int(tokens[pos])
                idx = [int(t) for t in tokens[pos + 1:pos + 1 + k]]
                pos += 1 + k
                faces.extend([idx[0], idx[i], idx[i + 1]] for i in range(1, k - 1))
        else:
            for line in f:
                parts = line.split()
                if not parts:
                    continue
                if parts[0] == "v":
                    vertices.append([float(t) for t in parts[1:4]])
                elif parts[0] == "f":
                    idx = [int(t.split("/")[0]) for t in parts[1:]]
                    idx = [i - 1 if i > 0 else len(vertices) + i for i in idx]
                    faces.extend([idx[0], idx[i], idx[i + 1]] for i in range(1, len(idx) - 1))
    return np.asarray(vertices, dtype=float), np.asarray(faces, dtype=np.int64)


class Trajectory:
    """The pointer centre: from vertex to a random near vertex in 0.25 s, offset along the interpolated
    vertex normal by r * (0.5 + 2.5 sin(2 pi t / 0.7 s)), i.e. from 3 r outside to 2 r inside."""

    def __init__(self, vertices, faces, seed=1):
        self.v = vertices
        n = np.zeros_like(vertices)
        fn = np.cross(vertices[faces[:, 1]] - vertices[faces[:, 0]], vertices[faces[:, 2]] - vertices[faces[:, 0]])
        for c in range(3):
            np.add.at(n, faces[:, c], fn)
        length = np.linalg.norm(n, axis=1)
        length[length == 0] = 1.0
        self.n = n / length[:, None]
        self.rng = np.random.default_rng(seed)
        self.diag = float(np.linalg.norm(vertices.max(0) - vertices.min(0)))
        self.current = int(self.rng.integers(len(vertices)))
        self.segment = 0.25

    def next_vertex(self):
        d = np.linalg.norm(self.v - self.v[self.current], axis=1)
        near = np.argsort(d)[1:40]
        return int(self.rng.choice(near))

    def segments(self):
        """Yields (start vertex, end vertex) forever."""
        while True:
            nxt = self.next_vertex()
            yield self.current, nxt
            self.current = nxt

    def position(self, a, b, s, t, radius):
        p = (1 - s) * self.v[a] + s * self.v[b]
        n = (1 - s) * self.n[a] + s * self.n[b]
        norm = np.linalg.norm(n)
        if norm > 0:
            n = n / norm
        return p + n * radius * (0.5 + 2.5 * math.sin(2 * math.pi * t / 0.7))


# ------------------------------------------------------------------------------------------------
# The run.

def free_port():
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


def read_rss_kib(pid):
    with open("/proc/%d/status" % pid) as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
    return -1


def node_pid(name, timeout=60.0):
    import rosgraph
    master = rosgraph.Master("/soak")
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        try:
            uri = master.lookupNode(name)
            code, _, pid = xmlrpc.client.ServerProxy(uri).getPid("/soak")
            if code == 1:
                return int(pid)
        except Exception:  # not registered yet
            pass
        time.sleep(0.2)
    raise RuntimeError("node %s did not register" % name)


def percentiles(values, qs=(50, 90, 99, 99.9)):
    if len(values) == 0:
        return {}
    out = {("p%g" % q): float(np.percentile(values, q)) for q in qs}
    out["max"] = float(np.max(values))
    return out


class Soak:
    def __init__(self, args):
        self.args = args
        self.ns = args.detector
        raw_v, faces = load_mesh(resolve_mesh(args.mesh))
        self.scale = args.scale
        self.trajectory = Trajectory(raw_v * self.scale, faces, seed=args.seed)
        self.triangles = len(faces)
        capacity = int(args.duration * args.rate * 1.05) + 10000
        self.sent_at = np.full(capacity, np.nan)
        self.recv_at = np.full(capacity, np.nan)
        self.detect_ns = np.zeros(capacity, dtype=np.int64)
        self.in_contact = np.zeros(capacity, dtype=bool)
        self.duplicates = 0
        self.foreign = 0
        self.last_answer_seq = None
        self.answer_gaps = 0  # answers the detector numbered but this subscriber never got
        self.dynparam_procs = []
        self.sent = 0
        self.marker_arrays = 0
        self.marker_bytes = 0
        self.status = None
        self.logs = []  # (level name, node, text)
        self.rss = []  # (elapsed s, KiB)
        self.reconfigures = 0
        self.reconfigure_failures = []
        self.radius = args.radii[0]
        self.stop = threading.Event()
        self.lock = threading.Lock()

    # Stamps: pose k carries stamp 1000 s + k microseconds, unique for the run.
    @staticmethod
    def stamp(k):
        import rospy
        return rospy.Time(1000 + k // 1000000, (k % 1000000) * 1000)

    @staticmethod
    def index(stamp):
        return (stamp.secs - 1000) * 1000000 + stamp.nsecs // 1000

    def on_contact(self, msg):
        seq = msg.header.seq
        if self.last_answer_seq is not None and seq > self.last_answer_seq + 1:
            self.answer_gaps += seq - self.last_answer_seq - 1
        self.last_answer_seq = seq
        k = self.index(msg.header.stamp)
        if k < 0 or k >= len(self.recv_at) or math.isnan(self.sent_at[k]):
            self.foreign += 1
            return
        if not math.isnan(self.recv_at[k]):
            self.duplicates += 1
            return
        self.recv_at[k] = time.monotonic()
        self.detect_ns[k] = msg.detection_time.secs * 1000000000 + msg.detection_time.nsecs
        self.in_contact[k] = msg.in_contact

    def on_markers(self, raw):
        self.marker_arrays += 1
        self.marker_bytes += len(raw._buff)

    def on_status(self, msg):
        self.status = msg

    def on_rosout(self, msg):
        if msg.level >= 4 and msg.name != "/rosout":
            name = {4: "WARN", 8: "ERROR", 16: "FATAL"}.get(msg.level, str(msg.level))
            with self.lock:
                self.logs.append((name, msg.name, msg.msg))

    def connect(self):
        import rospy
        from clod_haptics.msg import Contact, DetectorStatus
        from geometry_msgs.msg import PoseStamped
        from rosgraph_msgs.msg import Log
        if not rospy.core.is_initialized():
            import rosgraph
            end = time.monotonic() + 60.0
            while not rosgraph.Master("/soak").is_online() and time.monotonic() < end:
                time.sleep(0.2)
            rospy.init_node("soak", disable_signals=True)
        rospy.Subscriber("/rosout", Log, self.on_rosout, queue_size=None)
        self.pose_pub = rospy.Publisher(self.args.pose_topic, PoseStamped, queue_size=2000, tcp_nodelay=True)
        rospy.Subscriber(self.ns + "/contact", Contact, self.on_contact, queue_size=None, tcp_nodelay=True,
                         buff_size=1 << 22)
        rospy.Subscriber(self.ns + "/status", DetectorStatus, self.on_status, queue_size=10)
        if not self.args.no_markers:
            rospy.Subscriber(self.ns + "/markers", rospy.AnyMsg, self.on_markers, queue_size=None,
                             buff_size=1 << 26)
        self.PoseStamped = PoseStamped

    def wait_ready(self, timeout=120.0):
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            s = self.status
            if s is not None and s.level_spheres > 0 and self.pose_pub.get_num_connections() > 0:
                time.sleep(0.5)  # the contact connection, established in parallel
                return True
            time.sleep(0.1)
        return False

    def stream(self, t0):
        """Publishes poses at the rate with absolute deadlines; late ones go out at once."""
        msg = self.PoseStamped()
        msg.header.frame_id = self.args.frame_id
        msg.pose.orientation.w = 1.0
        period = 1.0 / self.args.rate
        per_segment = max(1, int(round(self.trajectory.segment * self.args.rate)))
        total = int(self.args.duration * self.args.rate)
        segments = self.trajectory.segments()
        k = 0
        while k < total and not self.stop.is_set():
            a, b = next(segments)
            for j in range(per_segment):
                if k >= total or self.stop.is_set():
                    break
                deadline = t0 + k * period
                now = time.monotonic()
                if deadline > now:
                    time.sleep(deadline - now)
                p = self.trajectory.position(a, b, j / per_segment, k * period, self.radius)
                msg.header.stamp = self.stamp(k)
                msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = float(p[0]), float(p[1]), float(p[2])
                self.sent_at[k] = time.monotonic()
                self.pose_pub.publish(msg)
                k += 1
        self.sent = k

    def reap_dynparam(self, wait=False):
        """Collects finished `dynparam set` processes; a non-zero exit is a failed reconfigure."""
        still = []
        for update, proc in self.dynparam_procs:
            if wait:
                try:
                    proc.wait(timeout=60)
                except subprocess.TimeoutExpired:
                    proc.kill()
                    proc.wait()
            if proc.poll() is None:
                still.append((update, proc))
            elif proc.returncode == 0:
                self.reconfigures += 1
            else:
                err = proc.stderr.read().decode(errors="replace").strip().splitlines()
                self.reconfigure_failures.append("%s: dynparam exit %d %s" % (update, proc.returncode, err[-1:]))
        self.dynparam_procs = still

    def reconfigurer(self, t0):
        if self.args.reconfigure_with == "dynparam":
            # A user at a shell: one `dynparam set` process started every period, not waited for (each one
            # takes 1 to 3 s to start Python and connect; several overlap).
            i = 0
            while not self.stop.wait(max(0.0, t0 + (i + 1) * self.args.reconfigure_period - time.monotonic())):
                i += 1
                d = self.args.distances[i % len(self.args.distances)]
                cmd = ["rosrun", "dynamic_reconfigure", "dynparam", "set", self.ns, "clustering_distance", repr(d)]
                self.dynparam_procs.append(({"clustering_distance": d}, subprocess.Popen(
                    cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)))
                self.reap_dynparam()
            self.reap_dynparam(wait=True)
            return
        import dynamic_reconfigure.client
        client = dynamic_reconfigure.client.Client(self.ns, timeout=30)
        i = 0
        while not self.stop.wait(max(0.0, t0 + (i + 1) * self.args.reconfigure_period - time.monotonic())):
            i += 1
            update = {"clustering_distance": self.args.distances[i % len(self.args.distances)]}
            if i % 4 == 0:
                update["pointer_radius"] = self.args.radii[(i // 4) % len(self.args.radii)]
            try:
                client.update_configuration(update)
                self.reconfigures += 1
                if "pointer_radius" in update:
                    self.radius = update["pointer_radius"]
            except Exception as e:  # counted and reported: a soak failure
                self.reconfigure_failures.append("%s: %s" % (update, e))

    def sample_rss(self, pid, t0):
        last_print = -RSS_PRINT_PERIOD
        while True:
            elapsed = time.monotonic() - t0
            try:
                kib = read_rss_kib(pid)
            except OSError:
                print("soak: [%6.1f s] the manager (pid %d) is gone" % (elapsed, pid), flush=True)
                return
            self.rss.append((elapsed, kib))
            if len(self.rss) == 1 or elapsed - last_print >= RSS_PRINT_PERIOD - 1e-6:
                last_print = elapsed
                print("soak: [%6.1f s] manager RSS %.1f MiB, poses %d, contacts %d, markers %d arrays" % (
                    elapsed, kib / 1024.0, int(np.count_nonzero(~np.isnan(self.sent_at))),
                    int(np.count_nonzero(~np.isnan(self.recv_at))), self.marker_arrays), flush=True)
            if self.stop.wait(RSS_SAMPLE_PERIOD):
                kib = read_rss_kib(pid)
                self.rss.append((time.monotonic() - t0, kib))
                print("soak: [%6.1f s] manager RSS %.1f MiB (end)" % (time.monotonic() - t0, kib / 1024.0),
                      flush=True)
                return

    def run(self, launch_alive=lambda: True):
        self.connect()
        pid = node_pid(self.args.manager)
        if not self.wait_ready():
            raise RuntimeError("the detector did not become ready (no level, or no pose subscriber)")
        status0 = self.status
        t0 = time.monotonic() + 0.2
        threads = [threading.Thread(target=self.sample_rss, args=(pid, t0), daemon=True),
                   threading.Thread(target=self.reconfigurer, args=(t0,), daemon=True)]
        for t in threads:
            t.start()
        self.stream(t0)
        stream_end = time.monotonic()
        # Answers still in flight: wait until the detector has answered what it received and we hold it.
        grace_end = stream_end + self.args.grace
        while time.monotonic() < grace_end:
            received = int(np.count_nonzero(~np.isnan(self.recv_at[:self.sent])))
            if received == self.sent:
                break
            time.sleep(0.05)
        self.stop.set()
        for t in threads:
            t.join(timeout=40)
        # A status (1 Hz) from after the last pose, for the detector's own counters.
        status_end = time.monotonic() + 2.5
        while time.monotonic() < status_end and (self.status is None or self.status.poses_received < self.sent):
            time.sleep(0.05)
        return self.report(status0, stream_end - t0, launch_alive())

    def report(self, status0, seconds, alive):
        a = self.args
        sent = self.sent
        answered = ~np.isnan(self.recv_at[:sent])
        n_answered = int(np.count_nonzero(answered))
        unanswered = sent - n_answered
        det_us = self.detect_ns[:sent][answered] / 1000.0
        rtt_us = (self.recv_at[:sent][answered] - self.sent_at[:sent][answered]) * 1e6
        s = self.status
        expected, unexpected = [], []
        with self.lock:
            logs = list(self.logs)
        for entry in logs:
            (expected if any(re.search(p, entry[2]) for p, _ in EXPECTED_WARNINGS) else unexpected).append(entry)
        rss = self.rss
        warm = [kib for t, kib in rss if t >= a.warmup]
        rss_warm = warm[0] if warm else None
        # A leak raises the floor the RSS comes back to between level builds; a build in flight (a grid's
        # temporaries) raises only a peak, which glibc returns. So the bound applies to the floor: the lowest RSS
        # over the last third of the samples after the warm-up against the lowest over the first third.
        third = max(1, len(warm) // 3)
        growth_mib = (min(warm[-third:]) - min(warm[:third])) / 1024.0 if warm else 0.0
        peak_mib = (max(warm) - rss_warm) / 1024.0 if warm else 0.0
        # The second half of the time after the warm-up: a steady leak grows here too, a one-time step may not.
        late = [kib for t, kib in rss if t >= (a.warmup + seconds) / 2.0] if rss else []
        late_mib = (max(late) - late[0]) / 1024.0 if late else 0.0

        failures = []
        if unanswered:
            failures.append("%d of %d poses unanswered" % (unanswered, sent))
        if s is not None and (s.poses_lost_upstream or s.poses_skipped_stale):
            failures.append("the detector counted %d poses lost upstream and %d skipped as stale" % (
                s.poses_lost_upstream, s.poses_skipped_stale))
        if self.answer_gaps:
            failures.append("%d answers lost between the detector and this subscriber (header.seq gaps)" %
                            self.answer_gaps)
        if sent == 0:
            failures.append("no pose sent")
        if warm and growth_mib > a.rss_bound_mib:
            failures.append("manager RSS floor grew by %.1f MiB after the warm-up (bound %.1f MiB)" %
                            (growth_mib, a.rss_bound_mib))
        if not warm:
            failures.append("no RSS sample after the %.0f s warm-up: run longer than the warm-up" % a.warmup)
        if unexpected:
            failures.append("%d unexpected warnings/errors" % len(unexpected))
        if self.reconfigure_failures:
            failures.append("%d reconfigure calls failed" % len(self.reconfigure_failures))
        if s is None or status0 is None or s.level_swaps <= status0.level_swaps:
            failures.append("no level swap: the reconfigures did not take effect")
        if not a.no_markers and self.marker_arrays == 0:
            failures.append("no marker array received while subscribed")
        if not alive:
            failures.append("the launch died")

        def fmt(p):
            return ", ".join("%s %.1f" % kv for kv in p.items())

        lines = [
            "== soak: detector nodelet, %s (scale %g, %d triangles scaled to %.3f m diagonal) ==" % (
                a.mesh, self.scale, self.triangles, self.trajectory.diag),
            "duration          %.1f s of stream (%.0f poses/s achieved, target %g)" % (
                seconds, sent / seconds if seconds > 0 else 0, a.rate),
            "poses sent        %d" % sent,
            "contacts received %d (in contact %.1f%%), duplicates %d, foreign %d" % (
                n_answered, 100.0 * np.count_nonzero(self.in_contact[:sent][answered]) / max(n_answered, 1),
                self.duplicates, self.foreign),
            "unanswered        %d%s" % (unanswered, (
                " (%d never reached the detector, %d answered by it but lost on the way back)" % (
                    sent - s.poses_received, unanswered - (sent - s.poses_received))
                if unanswered and s is not None else "")),
            "detector status   received %s, published %s, dropped non-finite %s, unknown frame %s, level swaps %s, "
            "level d = %s with %s spheres (%s)" % (
                (s.poses_received, s.contacts_published, s.dropped_non_finite, s.dropped_unknown_frame,
                 s.level_swaps - (status0.level_swaps if status0 else 0), s.clustering_distance, s.level_spheres,
                 s.level_source) if s else ("?",) * 8),
            "pose loss         policy %s, queues %s/%s: lost upstream %s, skipped stale %s, answers lost on the way "
            "back %d" % (((s.pose_policy, s.pose_queue_size, s.publish_queue_size, s.poses_lost_upstream,
                           s.poses_skipped_stale) if s else ("?",) * 5) + (self.answer_gaps,)),
            "pose path us      p50 %s, p99 %s, p99.9 %s, max %s (in the detector: roscpp receipt to answer "
            "published, every answered pose)" % ((s.pose_path_p50_us, s.pose_path_p99_us, s.pose_path_p999_us,
                                                 s.pose_path_max_us) if s else ("?",) * 4),
            "reconfigures      %d by %s (clustering_distance every %g s over %s%s), %d failed" % (
                self.reconfigures, "a dynparam process each" if a.reconfigure_with == "dynparam" else "this process",
                a.reconfigure_period, a.distances,
                "" if a.reconfigure_with == "dynparam" else ", pointer_radius every 4th over %s" % (a.radii,),
                len(self.reconfigure_failures)),
            "markers           %d arrays, %.1f MiB" % (self.marker_arrays, self.marker_bytes / 2.0 ** 20),
            "manager RSS       start %.1f MiB, after %.0f s warm-up %s MiB, end %.1f MiB, max %.1f MiB; "
            "floor growth after warm-up %.1f MiB (bound %.1f MiB), peak above the warm-up value %.1f MiB, "
            "over the last %.0f s %.1f MiB" % (
                rss[0][1] / 1024.0 if rss else -1, a.warmup,
                "%.1f" % (rss_warm / 1024.0) if rss_warm else "?", rss[-1][1] / 1024.0 if rss else -1,
                max(k for _, k in rss) / 1024.0 if rss else -1, growth_mib, a.rss_bound_mib, peak_mib,
                (seconds - a.warmup) / 2.0, late_mib),
            "detection time us %s" % fmt(percentiles(det_us)),
            "pose->contact us  %s (Python publisher to Python subscriber, includes both)" % fmt(percentiles(rtt_us)),
            "warnings          %d expected, %d unexpected" % (len(expected), len(unexpected)),
        ]
        seen = {}
        for level, node, text in unexpected:
            seen[(level, node, text)] = seen.get((level, node, text), 0) + 1
        for (level, node, text), count in list(seen.items())[:20]:
            lines.append("  unexpected %s %s (x%d): %s" % (level, node, count, text))
        for f in self.reconfigure_failures[:5]:
            lines.append("  reconfigure failed: %s" % f)
        lines.append("RESULT: %s" % ("PASS" if not failures else "FAIL: " + "; ".join(failures)))
        return {
            "text": "\n".join(lines), "failures": failures, "sent": sent, "answered": n_answered,
            "unanswered": unanswered, "answer_gaps": self.answer_gaps, "status": s, "rss": rss, "growth_mib": growth_mib, "late_growth_mib": late_mib, "detection_us": percentiles(det_us),
            "expected": expected, "unexpected": unexpected, "reconfigures": self.reconfigures,
            "marker_arrays": self.marker_arrays,
        }


def parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--duration", type=float, default=600.0, help="seconds of 1 kHz stream (default 600)")
    p.add_argument("--rate", type=float, default=1000.0, help="poses per second")
    p.add_argument("--mesh", default=None, help="mesh (default: ../shared mannequin-devil.off, else the torus)")
    p.add_argument("--scale", type=float, default=None, help="file units to metres (default: largest extent --size)")
    p.add_argument("--size", type=float, default=0.15, help="model size in metres when --scale is not given")
    p.add_argument("--distances", type=lambda s: [float(x) for x in s.split(",")],
                   default=[0.003, 0.0, 0.001, 0.002, 0.005, 0.008], help="clustering distances cycled (m)")
    p.add_argument("--radii", type=lambda s: [float(x) for x in s.split(",")], default=[0.002, 0.0015, 0.003],
                   help="pointer radii cycled every fourth reconfigure (m)")
    p.add_argument("--reconfigure-period", type=float, default=1.0, help="seconds between reconfigures")
    p.add_argument("--reconfigure-with", choices=["client", "dynparam"], default="dynparam",
                   help="client: a dynamic_reconfigure client in this process; dynparam (default): start a "
                        "`dynparam set` process every period, as a user at a shell does")
    p.add_argument("--warmup", type=float, default=None,
                   help="seconds before the RSS reference (default: max(60, a full distance cycle + 10) "
                        "or a third of short runs)")
    p.add_argument("--rss-bound-mib", type=float, default=32.0, help="allowed RSS growth after the warm-up")
    p.add_argument("--grace", type=float, default=5.0, help="seconds to wait for the last answers")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--no-markers", action="store_true", help="do not subscribe to ~markers")
    p.add_argument("--attach", action="store_true", help="use nodes already running (clod_haptics.launch) and their master")
    p.add_argument("--detector", default="/detector")
    p.add_argument("--manager", default="/clod_manager")
    p.add_argument("--pose-topic", default="/phantom/pose")
    p.add_argument("--frame-id", default="world")
    p.add_argument("--port", type=int, default=None, help="master port (default: a free one)")
    p.add_argument("--log", default=None, help="launch log (default: a temporary file)")
    args = p.parse_args(argv)
    if args.mesh is None:
        args.mesh = DEFAULT_MESH if os.path.exists(DEFAULT_MESH) else FALLBACK_MESH
    if args.scale is None:
        v, _ = load_mesh(resolve_mesh(args.mesh))
        args.scale = args.size / float((v.max(0) - v.min(0)).max())
    if args.warmup is None:
        cycle = len(args.distances) * args.reconfigure_period
        args.warmup = max(60.0, cycle + 10.0) if args.duration >= 180 else max(cycle, args.duration / 3.0)
    return args


def main():
    args = parse_args()
    if args.attach:
        result = Soak(args).run()
        print(result["text"], flush=True)
        return 1 if result["failures"] else 0

    port = args.port or free_port()
    os.environ["ROS_MASTER_URI"] = "http://localhost:%d" % port
    log_path = args.log or tempfile.mkstemp(prefix="clod_soak.", suffix=".log")[1]
    print("soak: %s for %.0f s at %g Hz, scale %g; master on port %d; launch log %s" % (
        args.mesh, args.duration, args.rate, args.scale, port, log_path), flush=True)
    log = open(log_path, "w")
    launch = subprocess.Popen(["roslaunch", "-p", str(port), "clod_haptics", "clod_haptics.launch",
                               "mesh:=" + os.path.abspath(resolve_mesh(args.mesh)), "scale:=%r" % args.scale,
                               "pointer_radius:=%r" % args.radii[0], "distance:=%r" % args.distances[0]],
                              stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
    code = 1
    try:
        result = Soak(args).run(launch_alive=lambda: launch.poll() is None)
        log.flush()
        # The launch log: errors, and nodes that died, before /rosout could see them.
        with open(log_path, errors="replace") as f:
            launch_problems = [line.strip() for line in f if re.search(r"\[ *(ERROR|FATAL) *\]|has died", line)]
        if launch_problems:
            result["failures"].append("%d ERROR/FATAL/died lines in the launch log" % len(launch_problems))
            result["text"] = result["text"].replace("RESULT: PASS", "RESULT: FAIL: launch log")
            result["text"] += "\n" + "\n".join("  launch log: " + line for line in launch_problems[:10])
        print(result["text"], flush=True)
        code = 1 if result["failures"] else 0
    except Exception as e:
        print("soak: FAIL: %s (launch log: %s)" % (e, log_path), flush=True)
        code = 1
    finally:
        if launch.poll() is None:
            os.killpg(launch.pid, signal.SIGINT)
            try:
                launch.wait(timeout=30)
            except subprocess.TimeoutExpired:
                os.killpg(launch.pid, signal.SIGKILL)
                launch.wait()
        log.close()
    if code == 0 and not args.log:
        os.unlink(log_path)
    return code


if __name__ == "__main__":
    sys.exit(main())
