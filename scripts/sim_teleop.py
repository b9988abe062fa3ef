#!/usr/bin/python3
"""Drive the robots of a simulated table from the keyboard (record.launch sim:=true).

A person demonstrating on the simulated table moves the robots with these keys, as they
would push real Hamsters by hand; the synthetic camera and the tracker see the motion and
the recorder records it. Keys:

    1..9      choose a robot (numbered as shown; the others stop)
    w / x     faster forward / backward (steps of 0.05 m/s)
    a / d     turn more to the left / right (steps of 1 rad/s)
    s, space  stop
    h         show these keys again
    q         quit (the robot stops)

The chosen robot's wheel speeds go to /robots/<robot>/wheels (ddace/WheelCommand) at
20 Hz; the robots are those sim_table publishes on /ddace/true_entities. A robot stops by
itself when no speeds come (sim_table's watchdog), so a closed terminal stops it.
"""
import os
import select
import sys
import termios
import tty

SPEED_STEP_MPS = 0.05
MAX_SPEED_MPS = 0.15
TURN_STEP_RADPS = 1.0
MAX_TURN_RADPS = 4.0
WHEEL_BASE_M = 0.03  # exec::DiffDriveParams' wheel_base_m, the simulated Hamster's
RATE_HZ = 20.0


class Teleop:
    """The key logic, free of ROS and terminals."""

    def __init__(self, robots):
        self.robots = robots
        self.chosen = 0
        self.v = 0.0
        self.w = 0.0

    def status(self):
        return "[%s] %.2f m/s, %.1f rad/s" % (self.robots[self.chosen], self.v, self.w)

    def wheels(self):
        """(left, right) ground speeds of the chosen robot, m/s."""
        half = 0.5 * self.w * WHEEL_BASE_M
        return self.v - half, self.v + half

    def handle(self, key):
        """Returns the robot to stop (another was chosen), 'quit', or None."""
        clamp = lambda x, m: max(-m, min(m, x))
        if key.isdigit() and 1 <= int(key) <= len(self.robots) and int(key) - 1 != self.chosen:
            stopped = self.robots[self.chosen]
            self.chosen, self.v, self.w = int(key) - 1, 0.0, 0.0
            return stopped
        if key == "w":
            self.v = clamp(self.v + SPEED_STEP_MPS, MAX_SPEED_MPS)
        elif key == "x":
            self.v = clamp(self.v - SPEED_STEP_MPS, MAX_SPEED_MPS)
        elif key == "a":
            self.w = clamp(self.w + TURN_STEP_RADPS, MAX_TURN_RADPS)
        elif key == "d":
            self.w = clamp(self.w - TURN_STEP_RADPS, MAX_TURN_RADPS)
        elif key in "s ":
            self.v = self.w = 0.0
        elif key == "q":
            self.v = self.w = 0.0
            return "quit"
        return None


def main():
    import rospy
    from ddace.msg import EntityArray, WheelCommand

    rospy.init_node("sim_teleop", disable_signals=True)
    node = rospy.get_name()
    unknown = sorted(n for n in rospy.get_param_names() if n.startswith(node + "/"))
    if unknown:
        sys.exit("sim_teleop: parameter%s %s: node %s reads none (its robots come from /ddace/true_entities)"
                 % ("s" if len(unknown) > 1 else "", ", ".join(unknown), node))
    if not sys.stdin.isatty():
        sys.exit("sim_teleop: needs a terminal for its keys (run it with rosrun in a terminal, "
                 "or start record.launch with sim:=true teleop:=true, which opens an xterm)")
    print("sim_teleop: waiting for the simulated table on /ddace/true_entities ...")
    try:
        truth = rospy.wait_for_message("/ddace/true_entities", EntityArray, timeout=30.0)
    except rospy.ROSException:
        sys.exit("sim_teleop: nothing on /ddace/true_entities within 30 s: is sim_table_node running?")
    robots = [e.name for e in truth.entities if e.kind == "robot"]
    if not robots:
        sys.exit("sim_teleop: the simulated table has no robots")
    pubs = {r: rospy.Publisher("/robots/%s/wheels" % r, WheelCommand, queue_size=5) for r in robots}
    teleop = Teleop(robots)

    def send(robot, left, right):
        msg = WheelCommand()
        msg.header.stamp = rospy.Time.now()
        msg.left_mps, msg.right_mps = left, right
        pubs[robot].publish(msg)

    def show_help():
        print(__doc__.split("Keys:")[1].split("The chosen")[0].rstrip())
        print("robots: " + "  ".join("%d=%s" % (i + 1, n) for i, n in enumerate(robots)))

    show_help()
    fd = sys.stdin.fileno()
    old = termios.tcgetattr(fd)
    tty.setcbreak(fd)
    try:
        last = None
        while not rospy.is_shutdown():
            line = teleop.status()
            if line != last:
                sys.stdout.write("\r\033[K" + line)
                sys.stdout.flush()
                last = line
            keys = ""
            if select.select([fd], [], [], 1.0 / RATE_HZ)[0]:
                # Every key typed since (a buffered read(1) would hold the others back).
                keys = os.read(fd, 64).decode(errors="replace")
                if not keys:  # the terminal closed
                    break
            quit_now = False
            for key in keys:
                if key == "h":
                    print()
                    show_help()
                    last = None
                what = teleop.handle(key)
                if what == "quit":
                    quit_now = True
                    break
                if what:
                    send(what, 0.0, 0.0)
            if quit_now:
                break
            send(robots[teleop.chosen], *teleop.wheels())
        send(robots[teleop.chosen], 0.0, 0.0)
    finally:
        termios.tcsetattr(sys.stdin, termios.TCSADRAIN, old)
        print()


if __name__ == "__main__":
    main()
