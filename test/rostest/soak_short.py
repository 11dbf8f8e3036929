#!/usr/bin/python3
"""rostest: scripts/soak.py for 20 s against the nodes of soak_short.test (soak.launch on the torus)."""
import os
import sys
import unittest

import rospkg
import rospy
import rostest

sys.path.insert(0, os.path.join(rospkg.RosPack().get_path("clod_haptics"), "scripts"))
import soak  # noqa: E402


class SoakShort(unittest.TestCase):
    def test_twenty_seconds_at_one_kilohertz(self):
        # The torus of soak.launch at scale 1; distances cycle every 2 s, the warm-up is one cycle.
        args = soak.parse_args(["--attach", "--duration", "20", "--scale", "1", "--reconfigure-period", "2",
                                "--distances", "0.003,0.0,0.002,0.006", "--mesh",
                                "package://clod_haptics/data/meshes/torus.obj"])
        result = soak.Soak(args).run()
        print(result["text"])
        self.assertEqual(result["failures"], [], result["text"])
        # The script measured what it claims to: poses went out at the rate and came back.
        self.assertGreater(result["sent"], 15000)
        self.assertEqual(result["answered"], result["sent"])
        self.assertGreaterEqual(result["reconfigures"], 8)
        self.assertGreater(result["marker_arrays"], 100)
        self.assertGreaterEqual(len(result["rss"]), 4)
        self.assertIn("p99", result["detection_us"])


if __name__ == "__main__":
    rospy.init_node("soak_short", disable_signals=True)
    rostest.rosrun("clod_haptics", "soak_short", SoakShort, sys.argv)
