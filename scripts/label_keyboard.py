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

Without any label the recorder infers them from the motion when the
demonstration is stopped (docs/labels.md); the tool then steps through the
inferred tokens for review (the ones to check first):

    n / p     next / previous token
    a / A     next / previous action for this token
    t / T     next / previous target for this token
    x         drop this token (the entity did nothing)
    w         write the corrections into the demonstration
    q         leave the review (unwritten corrections are dropped)

The review also runs without ROS on a saved demonstration:
    label_keyboard.py --review TASKDIR/demos/demo_000.csv
"""
import csv
import io
import os
import re
import select
import sys
import termios
import tty

import yaml


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


class Reviewer:
    """Steps through the tokens of a labelled demonstration CSV (ddace-task/1) to accept
    or correct them; ROS- and terminal-free. A token is a run of rows in which an entity's
    (action, target) stays the same and is not idle; corrections change exactly its rows."""

    def __init__(self, text, entities, actions, notes=()):
        self.rows = list(csv.reader(io.StringIO(text)))
        if not self.rows:
            raise ValueError("empty demonstration")
        self.header = self.rows[0]
        self.entities = entities
        self.actions = list(actions) or ["move"]
        self.columns = {}  # entity -> (action column, target column)
        for e in entities:
            if e + ".action" in self.header and e + ".target" in self.header:
                self.columns[e] = (self.header.index(e + ".action"), self.header.index(e + ".target"))
        self.tokens = []  # dicts: entity, action, target, first, last (data row indices)
        for e, (ca, ct) in self.columns.items():
            run = None
            for i, row in enumerate(self.rows[1:]):
                label = (row[ca], row[ct]) if row[ca] not in ("", "idle") else None
                if run and label == (run["action"], run["target"]):
                    run["last"] = i
                    continue
                run = None
                if label:
                    run = {"entity": e, "action": label[0], "target": label[1], "first": i, "last": i}
                    self.tokens.append(run)
        self.tokens.sort(key=lambda t: (t["first"], entities.index(t["entity"])))
        # Notes name file lines (the header is line 1): a token whose rows hold one is to check.
        self.notes = {}
        for line, message in notes:
            for t in self.tokens:
                if t["first"] <= line - 2 <= t["last"] + 1:
                    self.notes.setdefault(id(t), []).append(message)
                    break
        checked = [t for t in self.tokens if id(t) in self.notes]
        self.current = self.tokens.index(checked[0]) if checked else 0
        self.changed = False

    def token(self):
        return self.tokens[self.current] if self.tokens else None

    def status(self):
        t = self.token()
        if t is None:
            return "no tokens"
        t_first = self.rows[1 + t["first"]][self.header.index("t")]
        text = "token %d/%d: %s:%s%s from t = %s s" % (self.current + 1, len(self.tokens), t["entity"], t["action"],
                                                       ":" + t["target"] if t["target"] else "", t_first)
        return text + ("  CHECK: " + "; ".join(self.notes[id(t)]) if id(t) in self.notes else "")

    def handle(self, key):
        """Returns 'write', 'quit' or None."""
        t = self.token()
        if key == "q":
            return "quit"
        if key == "w":
            return "write"
        if t is None:
            return None
        if key in "np":
            self.current = (self.current + (1 if key == "n" else -1)) % len(self.tokens)
        elif key in "aA":
            i = self.actions.index(t["action"]) if t["action"] in self.actions else -1
            self._set(t, action=self.actions[(i + (1 if key == "a" else -1)) % len(self.actions)])
        elif key in "tT":
            options = [""] + [e for e in self.entities if e != t["entity"]]
            i = options.index(t["target"]) if t["target"] in options else 0
            self._set(t, target=options[(i + (1 if key == "t" else -1)) % len(options)])
        elif key == "x":
            self._set(t, action="", target="")
            self.tokens.remove(t)
            self.current = min(self.current, max(len(self.tokens) - 1, 0))
        return None

    def _set(self, t, action=None, target=None):
        ca, ct = self.columns[t["entity"]]
        for row in self.rows[1 + t["first"]:2 + t["last"]]:
            if action is not None:
                row[ca] = action
            if target is not None:
                row[ct] = target
        if action is not None:
            t["action"] = action
        if target is not None:
            t["target"] = target
        self.changed = True

    def text(self):
        out = io.StringIO()
        csv.writer(out, lineterminator="\n").writerows(self.rows)
        return out.getvalue()


def write_atomically(path, text):
    tmp = "%s.review-%d" % (path, os.getpid())
    with open(tmp, "w") as f:
        f.write(text)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)


def notes_of(message):
    """(line, message) of every 'demos/demo_000.csv:47: ...' line of a recorder message."""
    return [(int(m.group(1)), m.group(2)) for m in re.finditer(r"\.csv:(\d+): (.*)", message)]


def review(reviewer, path, read_key, say):
    """The review loop: keys from read_key(), lines to say(); writes `path` on 'w'."""
    say(reviewer.status())
    while True:
        key = read_key()
        if key is None:
            return
        what = reviewer.handle(key)
        if what == "quit":
            say("review left" + (" (corrections not written)" if reviewer.changed else ""))
            return
        if what == "write":
            write_atomically(path, reviewer.text())
            reviewer.changed = False
            say("wrote " + path)
            continue
        say(reviewer.status())


def load(path, what):
    try:
        with open(path) as f:
            return yaml.safe_load(f)
    except (OSError, yaml.YAMLError) as e:
        sys.exit("label_keyboard: cannot read %s %s: %s" % (what, path, e))


def read_key_blocking():
    # From the file descriptor, never through sys.stdin's buffer: a buffered read takes every
    # key typed so far into Python's buffer, where select() on the descriptor no longer sees
    # them, so keys typed together (or pasted) were held back until the next one.
    return os.read(sys.stdin.fileno(), 1).decode(errors="replace")


def read_pending_keys():
    """Every key typed since the last look, once select() said there is one."""
    return os.read(sys.stdin.fileno(), 64).decode(errors="replace")


def review_file(path):
    """--review PATH: the review of a saved demonstration, without ROS."""
    task = load(os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(path))), "task.yaml"), "task file")
    entities = [e["name"] for e in task.get("entities", [])]
    with open(path) as f:
        reviewer = Reviewer(f.read(), entities, task.get("actions") or [])
    if not sys.stdin.isatty():
        sys.exit("label_keyboard: needs a terminal for its keys")
    old = termios.tcgetattr(sys.stdin)
    tty.setcbreak(sys.stdin.fileno())
    try:
        review(reviewer, path, read_key_blocking, lambda line: print("\r\033[K" + line))
    finally:
        termios.tcsetattr(sys.stdin, termios.TCSADRAIN, old)


def main():
    if len(sys.argv) >= 3 and sys.argv[1] == "--review":
        return review_file(sys.argv[2])
    import rospy
    from std_msgs.msg import String
    from std_srvs.srv import Trigger

    from ddace.msg import Label

    rospy.init_node("label_keyboard", disable_signals=True)
    node, params = rospy.get_name(), ("markers_file", "recorder_file", "recorder")
    # As the C++ nodes (src/ros/params.cpp): a parameter of its namespace it does not read
    # (a typo, another node's) stops it rather than leaving a setting on its default.
    unknown = sorted(n for n in rospy.get_param_names()
                     if n.startswith(node + "/") and n[len(node) + 1:].split("/")[0] not in params)
    if unknown:
        sys.exit("label_keyboard: parameter%s %s %s not one of node %s's (a typo, or a parameter of another node, "
                 "would leave it on its default); its parameters: %s"
                 % ("s" if len(unknown) > 1 else "", ", ".join(unknown), "are" if len(unknown) > 1 else "is", node,
                    ", ".join(params)))
    for required in params[:2]:
        if not rospy.has_param("~" + required):
            sys.exit("label_keyboard: parameter %s/%s is required" % (node, required))
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
            for key in read_pending_keys():
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
                            if read_key_blocking() != "y":
                                print("kept")
                                continue
                        try:
                            res = services[what[1]]()
                            print("\r\033[K%s: %s" % (what[1], res.message))
                        except (rospy.ServiceException, rospy.ROSException) as e:
                            print("\r\033[K%s failed: %s (is recorder_node running as %s?)" % (what[1], e, recorder))
                            continue
                        # Labels inferred on stop: step through them to accept or correct them.
                        saved = re.match(r"saved (\S+):", res.message)
                        if what[1] == "stop" and res.success and saved and "labels inferred" in res.message:
                            path = saved.group(1)
                            with open(path) as f:
                                reviewer = Reviewer(f.read(), entities, actions, notes_of(res.message))
                            print("review of %s (n/p token, a/A action, t/T target, x drop, w write, q leave)" % path)
                            review(reviewer, path, read_key_blocking, lambda line: print("\r\033[K" + line))
                    last = None
    finally:
        termios.tcsetattr(sys.stdin, termios.TCSADRAIN, old)
        print()


if __name__ == "__main__":
    main()
