#!/usr/bin/python3
"""Keyboard labelling of demonstrations for recorder_node (docs/vision.md).

Run it in a terminal next to the recorder:
    rosrun ddace label_keyboard.py _markers_file:=... _recorder_file:=...
(record.launch starts it in an xterm). Keys:

    1..9      choose an entity (robots and objects, numbered as shown)
    a / A     next / previous action of the task's vocabulary
    t / T     next / previous target (any entity, or none)
    space     apply: the chosen entity does <action> toward <target> from now on
    i         the chosen entity goes idle (no action)
    c         every entity goes idle
    s         start a demonstration (recorder ~start)
    e         end it: stop and save (recorder ~stop)
    d         discard it (asks y/n)
    h         show these keys again
    q         quit

Labels go to /ddace/labels (ddace/Label). Demonstrations are step-synchronous
(docs/task-format.md): give the labels of one step together, and the next
step's only after every motion of the previous one has ended.
"""
import select
import sys
import termios
import tty

import rospy
import yaml
from std_msgs.msg import String
from std_srvs.srv import Trigger

from ddace.msg import Label


class Labeller:
    """The key logic, free of ROS and terminals: handle() returns what to do."""

    def __init__(self, entities, kinds, actions):
        self.entities = entities                 # every entity name, task order
        self.labelled = [n for n, k in zip(entities, kinds) if k != "goal"]
        self.actions = actions or ["move"]
        self.chosen = 0
        self.action = 0
        self.target = ""                          # entity name, "" = none

    def targets(self):
        """None first, then every entity but the chosen one (nothing targets itself)."""
        return [""] + [e for e in self.entities if e != self.labelled[self.chosen]]

    def current(self):
        return self.labelled[self.chosen], self.actions[self.action], self.target

    def status(self):
        entity, action, target = self.current()
        return "[%s] %s -> %s" % (entity, action, target or "(no target)")

    def handle(self, key):
        """Returns a list of ('label', entity, action, target) / ('service', name) / ('quit',)."""
        if key.isdigit() and 1 <= int(key) <= len(self.labelled):
            self.chosen = int(key) - 1
            if self.target == self.labelled[self.chosen]:
                self.target = ""
        elif key in "aA":
            self.action = (self.action + (1 if key == "a" else -1)) % len(self.actions)
        elif key in "tT":
            options = self.targets()
            i = options.index(self.target) if self.target in options else 0
            self.target = options[(i + (1 if key == "t" else -1)) % len(options)]
        elif key == " ":
            return [("label",) + self.current()]
        elif key == "i":
            return [("label", self.labelled[self.chosen], "", "")]
        elif key == "c":
            return [("label", e, "", "") for e in self.labelled]
        elif key == "s":
            return [("service", "start")]
        elif key == "e":
            return [("service", "stop")]
        elif key == "d":
            return [("service", "discard")]
        elif key == "q":
            return [("quit",)]
        return []


def load(path, what):
    try:
        with open(path) as f:
            return yaml.safe_load(f)
    except (OSError, yaml.YAMLError) as e:
        sys.exit("label_keyboard: cannot read %s %s: %s" % (what, path, e))


def main():
    rospy.init_node("label_keyboard", disable_signals=True)
    markers = load(rospy.get_param("~markers_file"), "markers file")
    recorder_cfg = load(rospy.get_param("~recorder_file"), "recorder file")
    recorder = rospy.get_param("~recorder", "/recorder")
    entities = [e["name"] for e in markers.get("entities", [])]
    kinds = [e.get("kind", "robot") for e in markers.get("entities", [])]
    actions = (recorder_cfg.get("task") or {}).get("actions") or []
    lab = Labeller(entities, kinds, actions)
    if not lab.labelled:
        sys.exit("label_keyboard: no robots or objects in the markers file")
    if not sys.stdin.isatty():
        sys.exit("label_keyboard: needs a terminal for its keys (run it with rosrun in a terminal, "
                 "or start record.launch with keyboard:=true, which opens an xterm)")

    pub = rospy.Publisher("/ddace/labels", Label, queue_size=10)
    state = {"text": "waiting for %s/state" % recorder}
    rospy.Subscriber(recorder + "/state", String, lambda m: state.update(text=m.data))
    services = {n: rospy.ServiceProxy("%s/%s" % (recorder, n), Trigger) for n in ("start", "stop", "discard")}

    def show_help():
        print(__doc__.split("Labels go")[0].split("Keys:")[1].rstrip())
        print("entities: " + "  ".join("%d=%s" % (i + 1, n) for i, n in enumerate(lab.labelled)))
        print("actions:  " + ", ".join(lab.actions))

    show_help()
    old = termios.tcgetattr(sys.stdin)
    tty.setcbreak(sys.stdin.fileno())
    try:
        last = None
        while not rospy.is_shutdown():
            line = "%s | recorder: %s" % (lab.status(), state["text"])
            if line != last:
                sys.stdout.write("\r\033[K" + line[:200])
                sys.stdout.flush()
                last = line
            if not select.select([sys.stdin], [], [], 0.1)[0]:
                continue
            key = sys.stdin.read(1)
            if key == "h":
                print()
                show_help()
                last = None
                continue
            for what in lab.handle(key):
                if what[0] == "quit":
                    return
                if what[0] == "label":
                    msg = Label()
                    msg.header.stamp = rospy.Time.now()
                    msg.entity, msg.action, msg.target = what[1], what[2], what[3]
                    pub.publish(msg)
                    print("\r\033[Klabel: %s %s %s" % (msg.entity, msg.action or "idle", msg.target))
                elif what[0] == "service":
                    if what[1] == "discard":
                        sys.stdout.write("\r\033[Kdiscard the current demonstration? [y/n] ")
                        sys.stdout.flush()
                        if sys.stdin.read(1) != "y":
                            print("kept")
                            continue
                    try:
                        res = services[what[1]]()
                        print("\r\033[K%s: %s" % (what[1], res.message))
                    except (rospy.ServiceException, rospy.ROSException) as e:
                        print("\r\033[K%s failed: %s (is recorder_node running as %s?)" % (what[1], e, recorder))
                last = None
    finally:
        termios.tcsetattr(sys.stdin, termios.TCSADRAIN, old)
        print()


if __name__ == "__main__":
    main()
