"""Shared helper of the planted bugs: replace one exact text in one file of the throwaway tree."""
import sys


def plant(path, old, new):
    tree = sys.argv[1]
    p = f"{tree}/{path}"
    s = open(p).read()
    if s.count(old) != 1:
        sys.exit(f"stale: the text to change is not (once) in {path}")
    open(p, "w").write(s.replace(old, new))
