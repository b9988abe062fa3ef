#!/usr/bin/python3
"""Measure a Hamster's speed calibration (m/s per wheel unit) with the overhead tracker.

Drives one robot through hamster_bridge_node in short straight runs, forward and back,
at a few speeds, and measures its true motion from the tracker's /ddace/entities.
The bridge turns the commanded m/s into wheel units with the calibration currently in
the config; comparing those units with the measured wheel speeds gives the true
m/s per unit of each wheel (least squares through the origin over all runs).

Usage (tracker and bridge running, the robot on the table with ~20 cm free in front
and behind):
    rosrun ddace calibrate_hamster.py _robot:=R1 [_config:=.../config/hamsters.yaml]
        [_speeds:="[0.03, 0.05, 0.07]"] [_run_s:=1.5] [_output:=/tmp/R1_calibration.yaml]

Private parameters:
    ~robot (str, required)      robot name (entity name in /ddace/entities, topics /robots/<robot>/...)
    ~config (str)               the bridge's config file (default: this package's config/hamsters.yaml)
    ~speeds (list of float)     commanded wheel speeds, m/s (each run forward and back)
    ~run_s (float)              duration of one run, s (default 1.5)
    ~settle_s (float)           ignored start of each run (acceleration), s (default 0.3)
    ~entities_topic (str)       default /ddace/entities
    ~output (str)               also write the result as YAML to this file
Prints the calibration block for config/hamsters.yaml. Exit status 1 with a message
naming the problem when the robot is not tracked, does not move, or a run saturates.
"""
import math
import os
import sys
import threading

import rospy
import yaml
from ddace.msg import EntityArray, WheelCommand


def round_half_away(x):
    """The bridge's rounding of wheel units (std::lround)."""
    return int(math.floor(abs(x) + 0.5)) * (1 if x >= 0 else -1)


def load_calibration(path, robot):
    with open(path) as f:
        config = yaml.safe_load(f)
    for r in config.get("robots", []):
        if r.get("name") == robot:
            cal = r.get("calibration", {})
            left = cal.get("left_mps_per_unit", cal.get("mps_per_unit"))
            right = cal.get("right_mps_per_unit", cal.get("mps_per_unit"))
            if left is None or right is None:
                raise ValueError(f"{path}: robot {robot} has no mps_per_unit in its calibration")
            return float(left), float(right), int(cal.get("max_units", 100)), float(cal.get("track_m", 0.033))
    raise ValueError(f"{path}: no robot named {robot}")


def fit_through_origin(xs, ys):
    sxx = sum(x * x for x in xs)
    if sxx == 0:
        raise ValueError("no wheel units commanded")
    k = sum(x * y for x, y in zip(xs, ys)) / sxx
    residual = math.sqrt(sum((y - k * x) ** 2 for x, y in zip(xs, ys)) / len(xs))
    return k, residual


# A robot that moved at under this fraction of the commanded speed did not follow the command
# (switched off, not linked, wheels blocked, another robot's marker): no calibration is fitted
# to it. A calibration ten times off is beyond what this fit is for.
FOLLOWED_FRACTION = 0.1

PARAMS = ("robot", "config", "speeds", "run_s", "settle_s", "output", "entities_topic")


def unknown_params(node, names, known):
    """The parameters of `names` under `node`'s private namespace that are not `known` (as
    the C++ nodes' check, src/ros/params.cpp): a typo or another node's would leave a
    setting on its default."""
    return sorted(n for n in names if n.startswith(node + "/") and n[len(node) + 1:].split("/")[0] not in known)


class Calibrator:
    def __init__(self):
        unknown = unknown_params(rospy.get_name(), rospy.get_param_names(), PARAMS)
        if unknown:
            raise ValueError("parameter%s %s %s not one of node %s's (a typo, or a parameter of another node, would "
                             "leave it on its default); its parameters: %s"
                             % ("s" if len(unknown) > 1 else "", ", ".join(unknown), "are" if len(unknown) > 1 else "is",
                                rospy.get_name(), ", ".join(PARAMS)))
        self.robot = rospy.get_param("~robot", "")
        if not self.robot:
            raise ValueError("parameter ~robot (robot name, e.g. R1) is required")
        default_config = os.path.join(os.path.dirname(os.path.realpath(__file__)), "..", "config", "hamsters.yaml")
        self.config = rospy.get_param("~config", default_config)
        self.speeds = [float(s) for s in rospy.get_param("~speeds", [0.03, 0.05, 0.07])]
        self.run_s = float(rospy.get_param("~run_s", 1.5))
        self.settle_s = float(rospy.get_param("~settle_s", 0.3))
        self.output = rospy.get_param("~output", "")
        if any(not (s > 0) for s in self.speeds):
            raise ValueError(f"~speeds must be positive m/s values, got {self.speeds}")
        if not self.run_s > self.settle_s + 0.2:
            raise ValueError(f"~run_s ({self.run_s}) must exceed ~settle_s ({self.settle_s}) by at least 0.2 s")
        self.k_left, self.k_right, self.max_units, self.track_m = load_calibration(self.config, self.robot)
        self.lock = threading.Lock()
        self.poses = []  # (stamp_s, x, y, theta)
        topic = rospy.get_param("~entities_topic", "/ddace/entities")
        self.sub = rospy.Subscriber(topic, EntityArray, self.on_entities, queue_size=20)
        self.pub = rospy.Publisher(f"/robots/{self.robot}/wheels", WheelCommand, queue_size=1)

    def on_entities(self, msg):
        for e in msg.entities:
            if e.name == self.robot and e.visible and not e.stale:
                with self.lock:
                    self.poses.append((msg.header.stamp.to_sec(), e.pose.x, e.pose.y, e.pose.theta))

    def drive(self, mps, seconds):
        """Commands both wheels at mps for seconds (50 Hz); returns the poses seen while driving."""
        with self.lock:
            self.poses = []
        rate = rospy.Rate(50)
        end = rospy.Time.now() + rospy.Duration(seconds)
        while not rospy.is_shutdown() and rospy.Time.now() < end:
            cmd = WheelCommand()
            cmd.header.stamp = rospy.Time.now()
            cmd.left_mps = mps
            cmd.right_mps = mps
            self.pub.publish(cmd)
            rate.sleep()
        with self.lock:
            return list(self.poses)

    def stop(self, seconds=0.4):
        self.drive(0.0, seconds)

    def measure(self, mps):
        """One run: returns (left units, right units, left m/s, right m/s) measured."""
        u_left = round_half_away(mps / self.k_left)
        u_right = round_half_away(mps / self.k_right)
        if max(abs(u_left), abs(u_right)) > self.max_units:
            raise ValueError(f"{mps} m/s needs {max(abs(u_left), abs(u_right))} wheel units > max_units "
                             f"{self.max_units}: choose smaller ~speeds")
        poses = self.drive(mps, self.run_s)
        if not poses:
            raise ValueError(f"robot {self.robot} is not tracked (no visible, non-stale entity on the entities topic)")
        t0 = poses[0][0] + self.settle_s
        steady = [p for p in poses if p[0] >= t0]
        if len(steady) < 5 or steady[-1][0] - steady[0][0] < 0.2:
            raise ValueError(f"too few tracker poses during the run ({len(steady)}): is the tracker running?")
        (ta, xa, ya, tha), (tb, xb, yb, thb) = steady[0], steady[-1]
        dt = tb - ta
        heading = tha + 0.5 * math.remainder(thb - tha, 2 * math.pi)
        forward = ((xb - xa) * math.cos(heading) + (yb - ya) * math.sin(heading)) / dt
        yaw_rate = math.remainder(thb - tha, 2 * math.pi) / dt
        if abs(forward) < FOLLOWED_FRACTION * abs(mps):
            raise ValueError(
                f"robot {self.robot} moved {forward:+.4f} m/s when commanded {mps:+.3f} m/s (units "
                f"{u_left:+d}/{u_right:+d}): it did not follow the command, and a calibration fitted to that would "
                f"drive it at full speed whatever is asked; nothing written. Is it switched on and linked (the "
                f"bridge says '{self.robot} streaming'), are its wheels free, is {self.robot}'s marker on it, and "
                f"does this graph drive it (on a simulated table recording, sim:=true, the teleop does)?")
        v_left = forward - yaw_rate * self.track_m / 2
        v_right = forward + yaw_rate * self.track_m / 2
        return u_left, u_right, v_left, v_right

    def run(self):
        rospy.loginfo("calibrate_hamster: %s, current calibration left %.6g right %.6g m/s/unit", self.robot,
                      self.k_left, self.k_right)
        rospy.sleep(1.0)  # let the connections come up
        self.stop()
        units_l, units_r, speeds_l, speeds_r = [], [], [], []
        for mps in self.speeds:
            for direction in (1.0, -1.0):  # forward, then back to where it started
                ul, ur, vl, vr = self.measure(direction * mps)
                self.stop()
                rospy.loginfo("calibrate_hamster: units %+d/%+d -> measured %+.4f/%+.4f m/s", ul, ur, vl, vr)
                units_l.append(ul)
                units_r.append(ur)
                speeds_l.append(vl)
                speeds_r.append(vr)
        k_left, res_left = fit_through_origin(units_l, speeds_l)
        k_right, res_right = fit_through_origin(units_r, speeds_r)
        if k_left <= 0 or k_right <= 0:
            raise ValueError(f"robot {self.robot} did not move forward when commanded forward "
                             f"(fit {k_left:.3g}/{k_right:.3g} m/s per unit): wrong robot or wheels reversed?")
        result = {
            "robot": self.robot,
            "left_mps_per_unit": round(k_left, 7),
            "right_mps_per_unit": round(k_right, 7),
            "rms_residual_mps": round(max(res_left, res_right), 6),
            "runs": len(units_l),
        }
        print(f"# {self.robot}: {len(units_l)} runs, RMS residual {max(res_left, res_right):.4f} m/s")
        print("    calibration: {left_mps_per_unit: %.7f, right_mps_per_unit: %.7f, max_units: %d, track_m: %g}"
              % (k_left, k_right, self.max_units, self.track_m))
        if self.output:
            with open(self.output, "w") as f:
                yaml.safe_dump(result, f)
        return result


def main():
    rospy.init_node("calibrate_hamster")
    try:
        Calibrator().run()
    except ValueError as e:
        print(f"calibrate_hamster: {e}", file=sys.stderr)
        return 1
    except rospy.ROSInterruptException:
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
