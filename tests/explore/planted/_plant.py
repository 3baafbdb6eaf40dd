"""Shared helper of the planted bugs: replace one exact text in one file of the throwaway tree.

Run on its own, `python3 tests/explore/planted/_plant.py --check [ROOT]` checks without building
that every planted bug still applies to the tree at ROOT (default: this repository): each
`N_*.py` runs in check mode, where `plant` reads the files but keeps its changes in memory (so
the bug's later replacements see its earlier ones, as on disk, and nothing is written), and the
violation it names (`KIND = "..."`) must still be a text of the explorer's sources, or no run
could ever be counted as catching it. A refactor that moves a planted text shows up here, in CI,
instead of as "not applied" in the next planted-bug table (issue 29 item 4: bug 1's text left
`pairing.rs` for `pairing/in_flight.rs` and nobody noticed)."""
import os
import subprocess
import sys

# Check mode: the files as the bug has changed them so far, by path.
_overlay = {}


def plant(path, old, new):
    tree = sys.argv[1]
    p = f"{tree}/{path}"
    checking = os.environ.get("PLANT_CHECK") == "1"
    if checking and p in _overlay:
        s = _overlay[p]
    else:
        try:
            with open(p) as f:
                s = f.read()
        except FileNotFoundError:
            sys.exit(f"stale: {path} does not exist")
    if s.count(old) != 1:
        sys.exit(f"stale: the text to change is not (once) in {path}")
    s = s.replace(old, new)
    if checking:
        _overlay[p] = s
    else:
        with open(p, "w") as f:
            f.write(s)


def _kind(path):
    """The violation a planted bug names (`KIND = "..."`), or None."""
    with open(path) as f:
        for line in f:
            if line.startswith('KIND = "') and line.rstrip().endswith('"'):
                return line.rstrip()[len('KIND = "') : -1]
    return None


def _explorer_sources(root):
    """Every Rust source of the explorer, as text."""
    texts = []
    for d, _, files in os.walk(os.path.join(root, "tests", "explore")):
        for name in sorted(files):
            if name.endswith(".rs"):
                with open(os.path.join(d, name)) as f:
                    texts.append(f.read())
    return texts


def check(root):
    """Checks every planted bug against the tree at `root`; returns the number of stale ones."""
    here = os.path.dirname(os.path.abspath(__file__))
    bugs = sorted(
        (f for f in os.listdir(here) if f[0].isdigit() and f.endswith(".py")),
        key=lambda f: int(f.split("_", 1)[0]),
    )
    sources = _explorer_sources(root)
    stale = 0
    for bug in bugs:
        problems = []
        kind = _kind(os.path.join(here, bug))
        if kind is None:
            problems.append('no KIND = "..." line')
        elif not any(kind in s for s in sources):
            problems.append(f"its violation {kind!r} is in no explorer source")
        run = subprocess.run(
            [sys.executable, bug, root],
            cwd=here,
            env={**os.environ, "PLANT_CHECK": "1"},
            capture_output=True,
            text=True,
        )
        if run.returncode != 0:
            problems.append((run.stderr.strip() or f"exit status {run.returncode}"))
        if problems:
            stale += 1
            print(f"{bug}: STALE: " + "; ".join(problems))
        else:
            print(f"{bug}: applies (violation {kind!r})")
    print(f"{len(bugs)} planted bugs, {stale} stale")
    return stale


if __name__ == "__main__":
    if len(sys.argv) < 2 or sys.argv[1] != "--check":
        sys.exit("usage: python3 _plant.py --check [ROOT]   (the bugs themselves import plant())")
    root = os.path.abspath(
        sys.argv[2] if len(sys.argv) > 2 else os.path.join(os.path.dirname(__file__), "../../..")
    )
    sys.exit(1 if check(root) else 0)
