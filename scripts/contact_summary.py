#!/usr/bin/env python3
"""Counts what the detector answered to a replayed stylus motion and prints a contact summary.

  contact_summary.py [--contact-topic T] [--pose-topic T] [--done-topic T] [--timeout S] [-- CMD ...]

With a command after `--` (a roslaunch line), starts it, waits until bag_replay reports the end
of its pass on --done-topic (std_msgs/UInt64, the poses it published) and the detector has
answered, prints the summary, then stops the command (SIGINT, then SIGTERM) and exits: 0 when
poses were replayed and every one was answered with a contact message, 1 otherwise (timeout,
nothing received, poses unanswered). `make demo` runs it.
"""
import argparse
import os
import signal
import subprocess
import sys
import threading
import time


def parse(argv):
    cmd = []
    if "--" in argv:
        i = argv.index("--")
        argv, cmd = argv[:i], argv[i + 1:]
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--contact-topic", default="/detector/contact")
    parser.add_argument("--pose-topic", default="/phantom/pose")
    parser.add_argument("--force-topic", default="/phantom/force_feedback")
    parser.add_argument("--done-topic", default="/bag_replay/done")
    parser.add_argument("--timeout", type=float, default=90.0, help="seconds for the whole run")
    parser.add_argument("--settle", type=float, default=2.0, help="seconds to wait for the last answers")
    parser.add_argument("--log", help="write the command's output here instead of the terminal")
    args = parser.parse_args(argv)
    return args, cmd


class Counter:
    def __init__(self):
        self.lock = threading.Lock()
        self.poses = 0
        self.first_pose = None
        self.last_pose = None
        self.contacts = 0
        self.in_contact = 0
        self.episodes = 0
        self.was_in = False
        self.max_depth = 0.0
        self.first_contact = None
        self.last_contact = None
        self.detection = []
        self.forces = 0
        self.max_force = 0.0
        self.done = None
        self.level = None

    def on_pose(self, _msg):
        now = time.monotonic()
        with self.lock:
            self.poses += 1
            self.first_pose = self.first_pose or now
            self.last_pose = now

    def on_contact(self, msg):
        now = time.monotonic()
        with self.lock:
            self.contacts += 1
            self.first_contact = self.first_contact or now
            self.last_contact = now
            if msg.in_contact:
                self.in_contact += 1
                self.max_depth = max(self.max_depth, msg.depth)
                if not self.was_in:
                    self.episodes += 1
            self.was_in = msg.in_contact
            self.detection.append(msg.detection_time.to_sec())
            self.level = (msg.clustering_distance, msg.level_spheres, msg.pointer_radius)

    def on_force(self, msg):
        f = msg.wrench.force
        with self.lock:
            self.forces += 1
            self.max_force = max(self.max_force, (f.x * f.x + f.y * f.y + f.z * f.z) ** 0.5)

    def on_done(self, msg):
        with self.lock:
            self.done = msg.data


def main(argv):
    args, cmd = parse(argv)
    proc = None
    if cmd:
        out = open(args.log, "w") if args.log else None
        proc = subprocess.Popen(cmd, start_new_session=True, stdout=out, stderr=subprocess.STDOUT if out else None)
    deadline = time.monotonic() + args.timeout
    status = 1
    try:
        import rospy
        from geometry_msgs.msg import PoseStamped, WrenchStamped
        from std_msgs.msg import UInt64
        from clod_haptics.msg import Contact

        while True:  # rospy.init_node waits for the master without a timeout: poll first
            try:
                import rosgraph
                if rosgraph.Master("/contact_summary").is_online():
                    break
            except Exception:
                pass
            if time.monotonic() > deadline or (proc and proc.poll() is not None):
                print("contact_summary: no ROS master (did the launch fail?)", file=sys.stderr)
                return 1
            time.sleep(0.2)
        rospy.init_node("contact_summary", anonymous=True, disable_signals=True)
        c = Counter()
        rospy.Subscriber(args.pose_topic, PoseStamped, c.on_pose, queue_size=10000, tcp_nodelay=True)
        rospy.Subscriber(args.contact_topic, Contact, c.on_contact, queue_size=10000, tcp_nodelay=True)
        rospy.Subscriber(args.force_topic, WrenchStamped, c.on_force, queue_size=10000, tcp_nodelay=True)
        rospy.Subscriber(args.done_topic, UInt64, c.on_done, queue_size=1)
        while c.done is None and time.monotonic() < deadline:
            if proc and proc.poll() is not None:
                print("contact_summary: the launch exited (code %s) before the replay ended" % proc.returncode,
                      file=sys.stderr)
                break
            time.sleep(0.1)
        # Let the last answers arrive.
        settle_end = min(deadline, time.monotonic() + args.settle)
        while time.monotonic() < settle_end:
            with c.lock:
                if c.done is not None and c.contacts >= c.done:
                    break
            time.sleep(0.05)
        with c.lock:
            pose_span = (c.last_pose - c.first_pose) if c.poses > 1 else 0.0
            contact_span = (c.last_contact - c.first_contact) if c.contacts > 1 else 0.0
            det = sorted(c.detection)
            median_us = 1e6 * det[len(det) // 2] if det else float("nan")
            p99_us = 1e6 * det[min(len(det) - 1, int(0.99 * len(det)))] if det else float("nan")
            print("== contact summary ==")
            print("poses replayed (bag_replay): %s" % ("timeout, no end of replay seen" if c.done is None else c.done))
            print("poses received here:         %d in %.2f s (%.0f Hz achieved)"
                  % (c.poses, pose_span, (c.poses - 1) / pose_span if pose_span > 0 else 0.0))
            print("contact messages:            %d in %.2f s (%.0f Hz achieved)"
                  % (c.contacts, contact_span, (c.contacts - 1) / contact_span if contact_span > 0 else 0.0))
            print("poses in contact:            %d (%.1f %%), %d contact episode(s), max depth %.2f mm"
                  % (c.in_contact, 100.0 * c.in_contact / c.contacts if c.contacts else 0.0, c.episodes,
                     1000 * c.max_depth))
            if c.level:
                print("level:                       d = %g, %d spheres, pointer radius %.2f mm"
                      % (c.level[0], c.level[1], 1000 * c.level[2]))
            print("detection time:              median %.1f us, 99th percentile %.1f us" % (median_us, p99_us))
            print("force messages:              %d, max %.3f N" % (c.forces, c.max_force))
            expected = c.done if c.done is not None else c.poses
            unanswered = max(0, expected - c.contacts)
            print("poses unanswered:            %d" % unanswered)
            ok = c.done is not None and c.done > 0 and unanswered == 0
            status = 0 if ok else 1
            if not ok:
                print("contact_summary: FAILED (replay end seen: %s, poses %s, contact messages %d)"
                      % (c.done is not None, expected, c.contacts), file=sys.stderr)
        rospy.signal_shutdown("summary done")
    finally:
        if proc and proc.poll() is None:
            os.killpg(proc.pid, signal.SIGINT)
            try:
                proc.wait(timeout=15)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGTERM)
                try:
                    proc.wait(timeout=5)
                except subprocess.TimeoutExpired:
                    os.killpg(proc.pid, signal.SIGKILL)
    return status


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
