#!/usr/bin/env python3
"""Which public client methods the explorer never calls (issue 29 item 2).

Lists every public method (`pub fn` / `pub async fn` in an inherent `impl` block of a public
type) of the client types, read from the source: every file under `src/**/client*` (wsg::Client
and ClientBuilder, griplink::Client, Port and its waits and watches, smartgrasp::Client,
wsg::text::Client) and the stream types they hand out (`src/wsg/subscription.rs`,
`src/wsg/text/push.rs`). A method counts as called when `.name(` or `::name(` occurs in the
explorer sources of its protocol (`tests/explore/<protocol>/**`, `tests/explore/wsg_text/**` for
wsg::text) or in the shared `tests/explore/core/**` and `tests/explore/main.rs`. Otherwise it must
be listed in `tests/explore/api-exempt.txt` as `protocol::Type::method | reason`, and the reason
must name the test that covers it instead: an existing `tests/….rs` path, and a test named in
backquotes after it must be in that file.

Strict (the default, CI): exits 1 when a method is neither called nor exempt, when an exempt line
names no such method or a method the explorer calls, or when a reason names no existing test.
`--report`: prints the same and exits 0. `--only PREFIX`: only the methods whose key starts with
PREFIX (e.g. `wsg::text::`), and only their exempt lines. Python 3 standard library only; reads
files, builds nothing.
"""
import os
import re
import sys

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))
EXEMPT = "tests/explore/api-exempt.txt"
# The stream types the clients hand out, beside the files under src/**/client*.
EXTRA_FILES = ["src/wsg/subscription.rs", "src/wsg/text/push.rs"]

IMPL_RE = re.compile(
    r"^impl(?:<[^{]*?>)?\s+([A-Za-z_][A-Za-z0-9_]*)(?:<[^{]*?>)?\s*(?:where[^{]*)?\{", re.S
)
FN_RE = re.compile(r"^\s*pub\s+(?:const\s+)?(?:async\s+)?(?:unsafe\s+)?fn\s+([a-z_][a-z0-9_]*)")
TYPE_RE = re.compile(r"^pub\s+(?:struct|enum)\s+([A-Za-z_][A-Za-z0-9_]*)", re.M)


def source_files():
    """The files that hold the client types' methods, relative to ROOT."""
    out = []
    for d, _, files in os.walk(os.path.join(ROOT, "src")):
        for name in files:
            path = os.path.relpath(os.path.join(d, name), ROOT)
            parts = path.split(os.sep)
            if name.endswith(".rs") and any(p.startswith("client") for p in parts[1:]):
                out.append(path)
    out.extend(EXTRA_FILES)
    return sorted(set(out))


def protocol(path):
    """`wsg`, `wsg::text`, `griplink`, `smartgrasp` (a file directly under src: its stem)."""
    parts = path.split(os.sep)[1:]
    if len(parts) == 1:
        return parts[0][: -len(".rs")]
    if parts[0] == "wsg" and parts[1] == "text":
        return "wsg::text"
    return parts[0]


def strip_comments(text):
    """The text without `//` comments and string literals' contents (line numbers kept)."""
    out = []
    for line in text.split("\n"):
        line = re.sub(r'"(?:\\.|[^"\\])*"', '""', line)
        i = line.find("//")
        out.append(line if i < 0 else line[:i])
    return "\n".join(out)


def public_types(files):
    types = set()
    for f in files:
        with open(os.path.join(ROOT, f)) as fh:
            types.update(TYPE_RE.findall(fh.read()))
    return types


def methods(files):
    """{(protocol, Type, method): file} of every public method of a public type's inherent impl."""
    types = public_types(files)
    found = {}
    for f in files:
        with open(os.path.join(ROOT, f)) as fh:
            text = strip_comments(fh.read())
        lines = text.split("\n")
        depth = 0
        current = None  # (type, depth of its body)
        skip_depth = None  # inside `#[cfg(test)]` items
        pending_cfg_test = False
        i = 0
        while i < len(lines):
            line = lines[i]
            stripped = line.strip()
            if stripped.startswith("#[cfg(test)]"):
                pending_cfg_test = True
            elif current is None and skip_depth is None and stripped.startswith("impl"):
                # The header may span lines up to its `{`.
                header = line
                j = i
                while "{" not in header and j + 1 < len(lines):
                    j += 1
                    header += "\n" + lines[j]
                m = IMPL_RE.match(header.strip())
                is_trait_impl = re.search(r"\bfor\s+[A-Za-z_]", header.split("{")[0]) is not None
                if m and not is_trait_impl and m.group(1) in types:
                    current = (m.group(1), depth + 1)
            elif current is not None and depth == current[1] and skip_depth is None:
                fm = FN_RE.match(line)
                if fm and not pending_cfg_test:
                    found[(protocol(f), current[0], fm.group(1))] = f
            if pending_cfg_test and ("{" in line or ";" in line) and not stripped.startswith("#["):
                if "{" in line and skip_depth is None:
                    skip_depth = depth
                pending_cfg_test = False
            depth += line.count("{") - line.count("}")
            if current is not None and depth < current[1]:
                current = None
            if skip_depth is not None and depth <= skip_depth:
                skip_depth = None
            i += 1
    return found


def explorer_text(proto):
    """The explorer sources a protocol's method may be called from."""
    base = os.path.join(ROOT, "tests", "explore")
    dirs = {
        "wsg": ["wsg"],
        "wsg::text": ["wsg_text"],
        "griplink": ["griplink"],
        "smartgrasp": ["smartgrasp"],
    }.get(proto, ["."])
    texts = []
    for sub in dirs + ["core"]:
        for d, _, files in os.walk(os.path.join(base, sub)):
            for name in sorted(files):
                if name.endswith(".rs"):
                    with open(os.path.join(d, name)) as fh:
                        texts.append(strip_comments(fh.read()))
    with open(os.path.join(base, "main.rs")) as fh:
        texts.append(strip_comments(fh.read()))
    return "\n".join(texts)


def called(text, name):
    return re.search(r"(?:\.|::)" + re.escape(name) + r"\s*(?:::<[^>]*>)?\s*\(", text) is not None


def read_exempt():
    """{key: (line number, reason)}, and the problems of the file's form."""
    out, problems = {}, []
    path = os.path.join(ROOT, EXEMPT)
    if not os.path.exists(path):
        return out, problems
    with open(path) as fh:
        for n, raw in enumerate(fh, 1):
            line = raw.strip()
            if not line or line.startswith("#"):
                continue
            key, sep, reason = line.partition("|")
            key, reason = key.strip(), reason.strip()
            if not sep or not reason:
                problems.append(f"{EXEMPT}:{n}: `{key}` has no reason (`KEY | reason`)")
                continue
            if key in out:
                problems.append(f"{EXEMPT}:{n}: `{key}` listed twice")
            out[key] = (n, reason)
    return out, problems


def reason_problems(n, key, reason):
    """A reason must name an existing test file, and a test in backquotes after it must exist."""
    tests = re.findall(r"(tests/[A-Za-z0-9_/]+\.rs)((?:\s*`[A-Za-z0-9_]+`(?:,|\s+and)?)*)", reason)
    if not tests:
        return [f"{EXEMPT}:{n}: `{key}`: the reason names no test (tests/NAME.rs `test_fn`)"]
    problems = []
    for path, names in tests:
        full = os.path.join(ROOT, path)
        if not os.path.exists(full):
            problems.append(f"{EXEMPT}:{n}: `{key}`: {path} does not exist")
            continue
        with open(full) as fh:
            text = fh.read()
        for fn in re.findall(r"`([A-Za-z0-9_]+)`", names):
            if not re.search(r"\bfn\s+" + re.escape(fn) + r"\b", text):
                problems.append(f"{EXEMPT}:{n}: `{key}`: no test `{fn}` in {path}")
    return problems


def main(argv):
    report = "--report" in argv
    only = argv[argv.index("--only") + 1] if "--only" in argv[:-1] else ""
    found = {
        k: f for k, f in methods(source_files()).items() if "::".join(k).startswith(only)
    }
    exempt, problems = read_exempt()
    exempt = {k: v for k, v in exempt.items() if k.startswith(only)}
    texts = {}
    per_type = {}
    missing = []
    for (proto, ty, name) in sorted(found):
        key = f"{proto}::{ty}::{name}"
        if proto not in texts:
            texts[proto] = explorer_text(proto)
        is_called = called(texts[proto], name)
        row = per_type.setdefault(f"{proto}::{ty}", [0, 0, 0])
        if is_called:
            row[0] += 1
            if key in exempt:
                problems.append(
                    f"{EXEMPT}:{exempt[key][0]}: `{key}` is called by the explorer: remove its line"
                )
        elif key in exempt:
            row[1] += 1
            problems.extend(reason_problems(exempt[key][0], key, exempt[key][1]))
        else:
            row[2] += 1
            missing.append(f"{key}  ({found[(proto, ty, name)]})")
    known = {f"{p}::{t}::{m}" for (p, t, m) in found}
    for key, (n, _) in sorted(exempt.items()):
        if key not in known:
            problems.append(f"{EXEMPT}:{n}: `{key}` is no public client method")
    print(f"{'type':<28} {'methods':>7} {'called':>7} {'exempt':>7} {'missing':>7}")
    total = [0, 0, 0]
    for ty, (c, e, m) in sorted(per_type.items()):
        print(f"{ty:<28} {c + e + m:>7} {c:>7} {e:>7} {m:>7}")
        total = [total[0] + c, total[1] + e, total[2] + m]
    print(f"{'all':<28} {sum(total):>7} {total[0]:>7} {total[1]:>7} {total[2]:>7}")
    if missing:
        print("\nnever called by an explorer workload, and not in " + EXEMPT + ":")
        for m in missing:
            print("  " + m)
    if problems:
        print("\n" + EXEMPT + ":")
        for p in problems:
            print("  " + p)
    failed = bool(missing or problems)
    if failed and not report:
        print(
            "\nFAILED: call each method from a workload (tests/explore/<protocol>/), or list it in "
            + EXEMPT
            + " with the test that covers it (`--report` only prints)"
        )
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
