#!/usr/bin/python3
"""rostest node: the install space works on its own (install_space.test).

Installs the build directory into its install space (cmake --install: what
`catkin_make install` does after building, catkin_ws/install by default), then, in an environment that sources only that prefix's
setup.bash: `rospack find ddace` is the installed share/ddace, `ddace generate` and
`ddace validate` run, execute_sim.launch replays a generated Task 4 on mock robots
until the execution monitor reports `finished` (against this test's ROS master), and the
installed plot_run.py draws that run.
"""
import json
import os
import shutil
import subprocess
import tempfile
import unittest

import rospy
import rostest


class InstallSpace(unittest.TestCase):
    prefix = ""
    work = ""

    @classmethod
    def setUpClass(cls):
        build_dir = rospy.get_param("~build_dir")
        cls.work = tempfile.mkdtemp(prefix="ddace_install_space_")
        # catkin writes the install space's setup files to the configured prefix only.
        with open(os.path.join(build_dir, "CMakeCache.txt")) as f:
            cls.prefix = next(line.split("=", 1)[1].strip() for line in f if line.startswith("CMAKE_INSTALL_PREFIX:"))
        r = subprocess.run(["cmake", "--install", build_dir], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        assert r.returncode == 0, "cmake --install failed:\n" + r.stdout[-3000:]

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.work, ignore_errors=True)

    def sh(self, script, timeout):
        """Runs `script` in bash with only the install space sourced; returns its output."""
        env = {"PATH": "/usr/bin:/bin", "HOME": self.work, "ROS_DISTRO": "Debian",
               "ROS_MASTER_URI": os.environ["ROS_MASTER_URI"], "ROS_HOSTNAME": "localhost",
               "ROS_HOME": os.path.join(self.work, "ros_home")}
        r = subprocess.run(["bash", "-c", 'source "%s/setup.bash" && %s' % (self.prefix, script)], env=env,
                           cwd=self.work, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=timeout)
        self.assertEqual(r.returncode, 0, "%s failed:\n%s" % (script, r.stdout[-4000:]))
        return r.stdout

    def test_package_is_the_installed_one(self):
        found = self.sh("rospack find ddace", 60).strip()
        self.assertEqual(found, os.path.join(self.prefix, "share", "ddace"))
        for f in ["launch/execute_sim.launch", "config/execution.yaml", "rviz/execute.rviz", "nodelet_plugins.xml",
                  "msg/Segment.msg"]:
            self.assertTrue(os.path.isfile(os.path.join(found, f)), f + " not installed")
        nodes = self.sh("rospack plugins --attrib=plugin nodelet | grep '^ddace '", 60)
        self.assertIn(os.path.join(self.prefix, "share", "ddace", "nodelet_plugins.xml"), nodes)

    def test_tool_and_launch_run_from_the_install_space(self):
        self.sh("rosrun ddace ddace generate task4 --out task4 --train 3 --test 2 --seed 3", 120)
        out = self.sh("rosrun ddace ddace validate task4/train task4/test", 60)
        self.assertNotIn("error", out.lower())
        # Every node and the Python labelling tool resolve to installed executables.
        args = self.sh("roslaunch --args /coordinator ddace execute_sim.launch task:=x", 60)
        self.assertTrue(args.startswith(os.path.join(self.prefix, "lib", "ddace", "coordinator_node")), args)
        run_dir = os.path.join(self.work, "run")
        self.sh("roslaunch ddace execute_sim.launch task:=%s/task4/test train:=%s/task4/train run_dir:=%s"
                % (self.work, self.work, run_dir), 300)
        with open(os.path.join(run_dir, "result.json")) as f:
            result = json.load(f)
        self.assertEqual(result["state"], "finished")
        # The monitor found the installed plot script next to its own executable.
        self.assertEqual(result["plot"], "paths.png")
        self.assertEqual(result["bag"], "run.bag")
        self.assertGreater(os.path.getsize(os.path.join(run_dir, "paths.png")), 1000)
        # The run's plot script is an installed program too (lib/ddace, python3-matplotlib).
        self.sh("rosrun ddace plot_run.py %s/run.json %s/replot.png" % (run_dir, self.work), 120)
        self.assertGreater(os.path.getsize(os.path.join(self.work, "replot.png")), 1000)


if __name__ == "__main__":
    rospy.init_node("install_space")
    rostest.rosrun("ddace", "install_space", InstallSpace)
