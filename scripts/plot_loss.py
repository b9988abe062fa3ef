#!/usr/bin/python3
"""Training loss vs epoch of the temporal graph network, as the paper's Fig. 4 and case studies.

Trains the models it needs with the project's own tool (`scripts/ddace generate` and
`scripts/ddace train`, into WORKDIR; existing models are reused) and reads each model
directory's loss.csv. Figures:

  fig4    one panel per task (1-4), one line per number of training demonstrations (10, 20, 30)
  task2   Task 2 with 4 ... 11 robots (30 demonstrations), log-scale loss
  task3   Task 3 with 2, 3, 4 actions (30 demonstrations)

Usage: scripts/plot_loss.py [--work WORKDIR] [--out DIR] [--only fig4,task2,task3]
       [--seed S] [--epochs N] [--jobs N] [--models MODELDIR...]
--jobs trains that many models at a time (each `ddace train` is single-threaded and
deterministic, so the curves do not depend on it).
With --models, plots the given model directories' loss curves in one figure instead.
"""
import argparse
import concurrent.futures
import csv
import os
import subprocess
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

REPO = os.path.dirname(os.path.dirname(os.path.realpath(__file__)))  # through the workspace symlink
DDACE = os.path.join(REPO, "scripts", "ddace")


def read_loss(model_dir):
    path = os.path.join(model_dir, "loss.csv")
    try:
        with open(path) as f:
            rows = list(csv.DictReader(f))
        return [int(r["epoch"]) for r in rows], [float(r["loss"]) for r in rows]
    except (OSError, KeyError, ValueError) as e:
        sys.exit("plot_loss: %s: not a readable loss.csv (%s)" % (path, e))


def run(cmd):
    result = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    if result.returncode != 0:
        sys.exit("plot_loss: %s failed:\n%s" % (" ".join(cmd), result.stdout))


def model(work, family, demos, seed, epochs, robots=None, actions=None):
    """Generates and trains one configuration (once); returns its model directory."""
    name = "%s_d%d" % (family, demos)
    extra = []
    if robots is not None:
        name += "_r%d" % robots
        extra += ["--robots", str(robots)]
    if actions is not None:
        name += "_a%d" % actions
        extra += ["--actions", str(actions)]
    data, out = os.path.join(work, "data", name), os.path.join(work, "models", name)
    if not os.path.exists(os.path.join(out, "loss.csv")):
        if not os.path.exists(os.path.join(data, "train", "task.yaml")):
            run([DDACE, "generate", family, "--out", data, "--train", str(demos), "--test", "1",
                 "--seed", str(seed)] + extra)
        print("training", name, flush=True)
        run([DDACE, "train", os.path.join(data, "train"), "--out", out, "--seed", str(seed), "--quiet"]
            + (["--epochs", str(epochs)] if epochs else []))
    return out


def save(fig, path):
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)
    print("wrote", os.path.relpath(path))


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--work", default=os.path.join(REPO, "catkin_ws", "plot_loss"), help="data and models")
    p.add_argument("--out", default=os.path.join(REPO, "docs", "figures"), help="directory for the PNGs")
    p.add_argument("--only", default="fig4,task2,task3")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--epochs", type=int, default=0, help="maximum epochs (default: the trainer's)")
    p.add_argument("--jobs", type=int, default=os.cpu_count() or 1, help="models trained at a time")
    p.add_argument("--models", nargs="*", help="plot these model directories instead")
    a = p.parse_args()
    os.makedirs(a.out, exist_ok=True)

    if a.models:
        fig, ax = plt.subplots(figsize=(6, 4))
        for m in a.models:
            ax.plot(*read_loss(m), label=os.path.basename(os.path.normpath(m)))
        ax.set_xlabel("epoch")
        ax.set_ylabel("training loss")
        ax.set_yscale("log")
        ax.legend()
        save(fig, os.path.join(a.out, "loss_models.png"))
        return

    only = set(a.only.split(","))
    unknown = only - {"fig4", "task2", "task3"}
    if unknown:
        sys.exit("plot_loss: --only: unknown figure(s) %s (fig4, task2, task3)" % ", ".join(sorted(unknown)))
    if not os.access(DDACE, os.X_OK):
        sys.exit("plot_loss: %s not found; run scripts/setup first" % DDACE)

    if a.jobs < 1:
        sys.exit("plot_loss: --jobs must be at least 1")
    # Every configuration the figures need, trained up front (in parallel); the plots
    # below then find each model in place.
    configs = []
    if "fig4" in only:
        configs += [dict(family=f, demos=d) for f in ("task1", "task2", "task3", "task4") for d in (10, 20, 30)]
    if "task2" in only:
        configs += [dict(family="task2", demos=30, robots=r) for r in range(4, 12)]
    if "task3" in only:
        configs += [dict(family="task3", demos=30, actions=k) for k in (2, 3, 4)]
    with concurrent.futures.ThreadPoolExecutor(max_workers=a.jobs) as pool:
        for future in [pool.submit(model, a.work, seed=a.seed, epochs=a.epochs, **c) for c in configs]:
            future.result()

    if "fig4" in only:
        fig, axes = plt.subplots(1, 4, figsize=(16, 3.6))
        for ax, family in zip(axes, ["task1", "task2", "task3", "task4"]):
            for demos in (10, 20, 30):
                ax.plot(*read_loss(model(a.work, family, demos, a.seed, a.epochs)), label="%d demos" % demos)
            ax.set_title(family)
            ax.set_xlabel("epoch")
            ax.set_ylabel("training loss")
            ax.legend()
        save(fig, os.path.join(a.out, "loss_fig4.png"))
    if "task2" in only:
        fig, ax = plt.subplots(figsize=(6, 4))
        for robots in range(4, 12):
            ax.plot(*read_loss(model(a.work, "task2", 30, a.seed, a.epochs, robots=robots)), label="%d robots" % robots)
        ax.set_yscale("log")
        ax.set_title("Task 2: team size")
        ax.set_xlabel("epoch")
        ax.set_ylabel("training loss (log)")
        ax.legend(ncol=2)
        save(fig, os.path.join(a.out, "loss_task2_robots.png"))
    if "task3" in only:
        fig, ax = plt.subplots(figsize=(6, 4))
        for actions in (2, 3, 4):
            ax.plot(*read_loss(model(a.work, "task3", 30, a.seed, a.epochs, actions=actions)), label="%d actions" % actions)
        ax.set_title("Task 3: vocabulary size")
        ax.set_xlabel("epoch")
        ax.set_ylabel("training loss")
        ax.legend()
        save(fig, os.path.join(a.out, "loss_task3_actions.png"))


if __name__ == "__main__":
    main()
