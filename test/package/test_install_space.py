#!/usr/bin/env python3
"""The install space serves a downstream package: test/downstream is copied into a workspace of its own,
built against the install space alone (its setup.bash in a clean environment: no devel space, no source
folder on ROS_PACKAGE_PATH) and its tests run there: a gtest of the installed core and a rostest of the
installed sphere_builder node. Their result files are copied beside this one, so their cases are counted
too; this file's cases: the installed layout, the downstream build, and that both downstream tests reported.

Usage: test_install_space.py PREFIX DOWNSTREAM_SRC WORK_DIR RESULT_XML (positional: catkin's run_tests.py
takes the options). PREFIX must hold a fresh `catkin_make install` (`make test` runs it first).
"""
import argparse
import glob
import os
import shutil
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from junit import write_result  # noqa: E402

# What a user of the installed package relies on (relative to PREFIX).
EXPECTED = [
    "setup.bash", "lib/libclod_core.so", "lib/libclod_ros.so", "lib/libclod_nodelets.so",
    "include/clod_haptics/core/detector.h", "include/clod_haptics/ros/conversions.h",
    "include/clod_haptics/GetSphereSet.h", "include/clod_haptics/Contact.h", "include/clod_haptics/DetectorConfig.h",
    "lib/clod_haptics/sphere_builder", "lib/clod_haptics/detector", "lib/clod_haptics/clod_tool",
    "lib/clod_haptics/bag_replay", "lib/clod_haptics/phantom_bridge", "lib/clod_haptics/contact_summary.py",
    "lib/clod_haptics/soak.py", "share/clod_haptics/package.xml", "share/clod_haptics/nodelet_plugins.xml",
    "share/clod_haptics/launch/clod_haptics.launch", "share/clod_haptics/config/detector.yaml",
    "share/clod_haptics/rviz/clod_haptics.rviz", "share/clod_haptics/data/meshes/torus.obj",
    "share/clod_haptics/data/bags/torus_stylus.bag", "share/clod_haptics/msg/Contact.msg",
    "share/clod_haptics/srv/GetSphereSet.srv", "share/clod_haptics/scripts/realtime_exec.sh",
    "share/clod_haptics/cmake/clod_hapticsConfig.cmake",
]


def check_layout(prefix):
    """Missing files, and links that leave the install space (it must stand without the sources)."""
    problems = ["missing: " + rel for rel in EXPECTED if not os.path.exists(os.path.join(prefix, rel))]
    real_prefix = os.path.realpath(prefix)
    for folder, dirs, files in os.walk(prefix):
        for name in dirs + files:
            path = os.path.join(folder, name)
            if os.path.islink(path) and not os.path.realpath(path).startswith(real_prefix + os.sep):
                problems.append("link out of the install space: %s -> %s" % (path, os.readlink(path)))
    if problems:
        return "the install space at %s is incomplete (`catkin_make install` first):\n%s" % (prefix, "\n".join(problems))
    return None


def clean_env(prefix, work):
    """Only what a fresh shell has; ROS comes from PREFIX/setup.bash."""
    env = {k: os.environ[k] for k in ("HOME", "LANG", "LC_ALL", "TERM", "USER") if k in os.environ}
    env.update(PATH="/usr/bin:/bin", PYENV_VERSION="system", CLOD_INSTALL_PREFIX=prefix,
               ROS_HOME=os.path.join(work, "ros_home"), ROS_LOG_DIR=os.path.join(work, "ros_home", "log"))
    return env


def run(script, env, log):
    """Runs a bash script in env, appending its output to log; returns the exit code."""
    with open(log, "a") as out:
        out.write("\n$ %s\n" % script)
        out.flush()
        return subprocess.run(["bash", "-c", script], env=env, stdout=out, stderr=subprocess.STDOUT,
                              timeout=1800).returncode


def build_and_test(prefix, source, work, results_dir):
    """Returns (build failure, results failure): None for each part that passed."""
    ws = os.path.join(work, "ws")
    shutil.rmtree(ws, ignore_errors=True)
    shutil.copytree(source, os.path.join(ws, "src", "clod_haptics_downstream"),
                    ignore=shutil.ignore_patterns("CATKIN_IGNORE"))
    log = os.path.join(work, "downstream.log")
    open(log, "w").close()
    env = clean_env(prefix, work)
    setup = "source %s/setup.bash && cd %s && " % (prefix, ws)
    if run(setup + 'case ":$ROS_PACKAGE_PATH:" in *"/src:"*|*devel*) echo "not the install space alone: '
           '$ROS_PACKAGE_PATH"; exit 1;; esac', env, log) != 0:
        return "the clean environment sees more than the install space (log: %s)" % log, "not run"
    if run(setup + "catkin_make -j1 --cmake-args -DCMAKE_BUILD_TYPE=Release --make-args all tests", env, log) != 0:
        return "the downstream package does not build against the install space (log: %s):\n%s" % (
            log, "".join(open(log).readlines()[-40:])), "not run"
    run(setup + "catkin_make -j1 run_tests", env, log)
    found = glob.glob(os.path.join(ws, "build", "test_results", "clod_haptics_downstream", "*.xml"))
    for path in found:
        os.makedirs(os.path.join(results_dir, "clod_haptics_downstream"), exist_ok=True)
        shutil.copy(path, os.path.join(results_dir, "clod_haptics_downstream", os.path.basename(path)))
    names = sorted(os.path.basename(p) for p in found)
    wanted = ["gtest-test_downstream_core.xml", "rostest-test_service.xml"]
    missing = [w for w in wanted if w not in names]
    if missing:
        return None, "downstream tests without a result: %s (found %s; log: %s)" % (missing, names, log)
    return None, None


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("install", help="the install space (PREFIX)")
    parser.add_argument("downstream", help="the downstream package's source folder")
    parser.add_argument("work", help="a scratch folder for its workspace and log")
    parser.add_argument("result", help="the JUnit file to write")
    args = parser.parse_args()
    prefix, work = os.path.abspath(args.install), os.path.abspath(args.work)
    os.makedirs(work, exist_ok=True)
    layout = check_layout(prefix)
    if layout:
        build, results = "not run: the install space is incomplete", "not run"
    else:
        build, results = build_and_test(prefix, os.path.abspath(args.downstream), work,
                                        os.path.dirname(os.path.dirname(os.path.abspath(args.result))))
    cases = [("install_space_layout", layout), ("downstream_builds", build), ("downstream_tests_reported", results)]
    write_result(args.result, "package", cases)
    for name, failure in cases:
        print("%s: %s" % (name, failure or "ok"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
