"""Finds import cycles between the files of src/ (issue 30, 4): file A uses a name of file B and B,
directly or through other files, uses a name of A.

Usage: python3 .ci/import_cycles.py [SRC_DIR]
       python3 .ci/import_cycles.py --self-test   (the checker on a small crate of known cycles)

What counts as a use: every `use` declaration and every path in the code that starts with
`crate::`, `super::` or `self::`, or with the name of a child module (`task::run(..)` in the file
that declares `mod task;`). A path is resolved to the file that *defines* the name, following
re-exports (`pub use child::Client` in a `mod.rs` is the façade, not a use of `child` by that
file; whoever names `super::Client` uses the file that defines `Client`). Names from other crates
(`std`, `tokio`, ...) are not ours. Comments, string literals and `#[cfg(test)]` modules are
skipped: a test module exercises its file and is not a part of the layering. A use of an
ancestor's own items (`super::Client` where `Client` is defined in the parent's `mod.rs`) is not an
edge: a child module is part of its parent's implementation, the way Rust's privacy sees it. So a
cycle is between files none of which is the other's ancestor: siblings, cousins, or a child and
its parent's sibling.

Prints every cycle (the strongly connected groups of files, with one path around each) and exits
1 if one is found that `EXEMPT` does not list, or if an exemption no longer matches a cycle (so
that it is removed once the cycle is gone). Python's standard library only.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

# Cycles known and being removed. Each entry is the exact set of files of one cycle, relative to
# src/ (a cycle that grows or shrinks no longer matches its entry). The WSG client's two are the
# `corea` branch's (its task and connector move onto the shared connection supervisor): the lead
# removes them when that branch is merged.
EXEMPT: list[frozenset[str]] = []

ITEM = re.compile(
    r"^\s*(?:pub(?:\([^)]*\))?\s+)?(?:unsafe\s+|async\s+|const\s+(?=fn))*"
    r"(?:struct|enum|fn|trait|type|const|static|union|mod|macro_rules!)\s+(\w+)",
    re.M,
)
USE = re.compile(r"^\s*(pub(?:\([^)]*\))?\s+)?use\s+([^;]+);", re.M)
MOD_DECL = re.compile(r"^\s*(?:pub(?:\([^)]*\))?\s+)?mod\s+(\w+)\s*;", re.M)
PATH = re.compile(r"(?<![\w:])((?:crate|super|self|[a-z_][a-z0-9_]*)(?:::\w+)+)")
MACRO_EXPORT = re.compile(r"#\[macro_export\][^\n]*\n\s*macro_rules!\s+(\w+)")


def strip(text: str) -> str:
    """The code without comments, string and char literals (kept as blanks, lines preserved)."""
    out = []
    i, n = 0, len(text)
    while i < n:
        c = text[i]
        if text.startswith("//", i):
            j = text.find("\n", i)
            i = n if j < 0 else j
        elif text.startswith("/*", i):
            depth, i = 1, i + 2
            while i < n and depth:
                if text.startswith("/*", i):
                    depth, i = depth + 1, i + 2
                elif text.startswith("*/", i):
                    depth, i = depth - 1, i + 2
                else:
                    if text[i] == "\n":
                        out.append("\n")
                    i += 1
        elif c == "r" and re.match(r'r#*"', text[i:]) and not (i and (text[i - 1].isalnum() or text[i - 1] == "_")):
            hashes = re.match(r"r(#*)\"", text[i:]).group(1)
            end = text.find('"' + hashes, i + 2 + len(hashes))
            end = n if end < 0 else end + 1 + len(hashes)
            out.append('""' + "\n" * text.count("\n", i, end))
            i = end
        elif c == '"':
            j = i + 1
            while j < n and text[j] != '"':
                j += 2 if text[j] == "\\" else 1
            out.append('""' + "\n" * text.count("\n", i, j))
            i = j + 1
        elif c == "'" and re.match(r"'(\\.|[^\\'])'|'\\u\{[0-9a-fA-F]+\}'|'\\x[0-9a-fA-F]{2}'", text[i:]):
            m = re.match(r"'(\\.|[^\\'])'|'\\u\{[0-9a-fA-F]+\}'|'\\x[0-9a-fA-F]{2}'", text[i:])
            out.append("' '")
            i += m.end()
        else:
            out.append(c)
            i += 1
    return "".join(out)


def drop_test_modules(code: str) -> str:
    """The code without `#[cfg(test)]` items (the test module and test-only helpers)."""
    while True:
        m = re.search(r"#\[cfg\(test\)\]\s*(?:#\[[^\]]*\]\s*)*", code)
        if not m:
            return code
        i = m.end()
        # The item ends at its `;` or at the brace that closes its first `{`.
        depth, j = 0, i
        while j < len(code):
            if code[j] == "{":
                depth += 1
            elif code[j] == "}":
                depth -= 1
                if depth == 0:
                    j += 1
                    break
            elif code[j] == ";" and depth == 0:
                j += 1
                break
            j += 1
        code = code[: m.start()] + "\n" * code.count("\n", m.start(), j) + code[j:]


def expand_use(tree: str) -> list[tuple[str, str]]:
    """`a::{b, c::d as e, f::*}` as [(path, name bound)]: [("a::b","b"), ("a::c::d","e"), ("a::f::*","*")]."""
    tree = re.sub(r"\s+", "", tree)
    out: list[tuple[str, str]] = []

    def walk(prefix: str, s: str) -> None:
        depth, start, parts = 0, 0, []
        for k, ch in enumerate(s):
            if ch == "{":
                depth += 1
            elif ch == "}":
                depth -= 1
            elif ch == "," and depth == 0:
                parts.append(s[start:k])
                start = k + 1
        parts.append(s[start:])
        for p in filter(None, parts):
            brace = p.find("{")
            if brace >= 0:
                walk(prefix + p[:brace], p[brace + 1 : p.rfind("}")])
                continue
            path, _, alias = p.partition("as")  # `as` has no `::` around it once spaces are gone
            if "::" in path and alias and not p.endswith("::as"):
                full = prefix + path
                out.append((full, alias))
            else:
                full = prefix + p
                name = full.rsplit("::", 1)[-1]
                if name == "self":
                    full = full[: -len("::self")]
                    name = full.rsplit("::", 1)[-1]
                out.append((full, name))

    walk("", tree)
    return out


class Crate:
    def __init__(self, src: Path) -> None:
        self.src = src
        self.files: dict[tuple[str, ...], Path] = {}  # module path -> file
        for f in sorted(src.rglob("*.rs")):
            rel = f.relative_to(src).with_suffix("")
            parts = list(rel.parts)
            if parts[-1] in ("mod", "lib", "main"):
                parts = parts[:-1]
            self.files[tuple(parts)] = f
        self.code = {m: drop_test_modules(strip(f.read_text())) for m, f in self.files.items()}
        # Module -> its own items (names defined in it), its imports (name -> absolute path
        # tuple, or a glob), and whether each import is a re-export.
        self.items: dict[tuple[str, ...], set[str]] = {}
        self.imports: dict[tuple[str, ...], dict[str, tuple[tuple[str, ...], bool]]] = {}
        self.globs: dict[tuple[str, ...], list[tuple[tuple[str, ...], bool]]] = {}
        self.macros: dict[str, tuple[str, ...]] = {}
        for m, code in self.code.items():
            self.items[m] = set(ITEM.findall(code))
            for name in MACRO_EXPORT.findall(code):
                self.macros[name] = m
            imports, globs = {}, []
            for vis, tree in USE.findall(code):
                for path, name in expand_use(tree):
                    absolute = self.absolute(m, path.split("::"))
                    if absolute is None:
                        continue
                    if name == "*":
                        globs.append((absolute[:-1], bool(vis)))
                    elif name != "_":
                        imports[name] = (absolute, bool(vis))
            self.imports[m] = imports
            self.globs[m] = globs

    def children(self, m: tuple[str, ...]) -> set[str]:
        return {k[-1] for k in self.files if len(k) == len(m) + 1 and k[: len(m)] == m}

    def absolute(self, m: tuple[str, ...], segs: list[str]) -> tuple[str, ...] | None:
        """`segs` written in module `m` as a path from the crate root, or None if not ours."""
        if not segs or not segs[0]:
            return None
        base = list(m)
        first = segs[0]
        if first == "crate":
            base, segs = [], segs[1:]
        elif first in ("super", "self"):
            while segs and segs[0] in ("super", "self"):
                if segs[0] == "super":
                    if not base:
                        return None
                    base.pop()
                segs = segs[1:]
        elif first in self.children(m) or first in self.imports.get(m, {}) or first in self.items.get(m, set()):
            pass  # a child module, or a name in scope: relative to `m`
        else:
            return None  # another crate (std, tokio, ...) or a local variable
        return tuple(base) + tuple(segs)

    def resolve(self, path: tuple[str, ...], seen: frozenset = frozenset()) -> tuple[str, ...] | None:
        """The module whose file defines the item (or is the module) `path` names."""
        if path in seen or len(seen) > 40:
            return None
        seen = seen | {path}
        m: tuple[str, ...] = ()
        for k, seg in enumerate(path):
            if m + (seg,) in self.files:
                m = m + (seg,)
                continue
            # `seg` is a name in module `m`: defined there, imported, or from a glob.
            if seg in self.items.get(m, set()):
                return m
            if seg in self.imports.get(m, {}):
                target = self.imports[m][seg][0] + path[k + 1 :]
                return self.resolve(target, seen)
            for glob, _ in self.globs.get(m, []):
                found = self.resolve(glob + (seg,) + path[k + 1 :], seen)
                if found is not None:
                    return found
            return m  # a name we cannot see (a variant, a method, a macro-made item): its module
        return m

    def edges(self) -> dict[tuple[str, ...], dict[tuple[str, ...], str]]:
        """File -> files it uses, each with one example of the use."""
        out: dict[tuple[str, ...], dict[tuple[str, ...], str]] = {m: {} for m in self.files}
        for m, code in self.code.items():
            uses: list[tuple[str, ...]] = []
            reexported = {name for name, (_, vis) in self.imports[m].items() if vis}
            for name, (path, vis) in self.imports[m].items():
                if not vis:
                    uses.append(path)
            for glob, vis in self.globs[m]:
                if not vis:
                    uses.append(glob)
            # Paths in the code outside `use` declarations.
            body = USE.sub(lambda u: "\n" * u.group(0).count("\n"), code)
            for p in PATH.findall(body):
                segs = p.split("::")
                if segs[0] in reexported:
                    continue
                absolute = self.absolute(m, segs)
                if absolute is not None:
                    uses.append(absolute)
            for path in uses:
                target = self.resolve(path)
                # A module's own file and its ancestors' are not edges: a child module is part
                # of its parent's implementation (Rust lets it see the parent's private items);
                # the parent's `mod.rs` holding the type its children implement parts of is
                # the layout, not a cycle.
                if target is None or m[: len(target)] == target:
                    continue
                out[m].setdefault(target, "::".join(path))
        return out


def sccs(graph: dict) -> list[list]:
    """Tarjan's strongly connected components (iterative)."""
    index: dict = {}
    low: dict = {}
    stack: list = []
    on: set = set()
    result: list[list] = []
    counter = 0
    for root in graph:
        if root in index:
            continue
        work = [(root, iter(graph[root]))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on.add(root)
        while work:
            v, it = work[-1]
            for w in it:
                if w not in index:
                    index[w] = low[w] = counter
                    counter += 1
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(graph[w])))
                    break
                if w in on:
                    low[v] = min(low[v], index[w])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[v])
                if low[v] == index[v]:
                    comp = []
                    while True:
                        w = stack.pop()
                        on.discard(w)
                        comp.append(w)
                        if w == v:
                            break
                    if len(comp) > 1:
                        result.append(comp)
    return result


def a_cycle(graph: dict, comp: list) -> list:
    """One path around the group, from its first file back to it (breadth-first: a shortest one)."""
    members = set(comp)
    start = min(comp)
    parents = {start: None}
    queue = [start]
    while queue:
        v = queue.pop(0)
        for w in sorted(graph[v]):
            if w == start:
                path = [v]
                while parents[path[-1]] is not None:
                    path.append(parents[path[-1]])
                return list(reversed(path)) + [start]
            if w in members and w not in parents:
                parents[w] = v
                queue.append(w)
    return comp


SELF_TEST = {
    "lib.rs": "mod a;\nmod b;\nmod p;\nmod q;\nmod r;\n",
    # a <-> b through a `use` and a path in the code: a cycle.
    "a.rs": "use crate::b::B;\npub struct A;\n",
    "b.rs": "pub struct B;\nfn f() { let _ = super::a::A; }\n",
    # The parent holds the type, the child implements part of it, the parent calls the child
    # and re-exports its type: the layout, not a cycle.
    "p/mod.rs": "mod c;\npub use c::C;\npub struct P;\nfn f() { c::g(); }\n",
    "p/c.rs": "use super::P;\npub struct C;\npub fn g() {}\n",
    # q uses r through p's re-export; r's use of q is in a comment, a string and a test module
    # only: no cycle.
    "q.rs": "use crate::p::C;\npub struct Q;\n",
    "r.rs": (
        "// use crate::q::Q;\n/* crate::q::Q */\nconst S: &str = \"crate::q::Q\";\n"
        "use crate::p::P;\n#[cfg(test)]\nmod tests {\n    use crate::q::Q;\n}\n"
    ),
}


def self_test() -> int:
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        for rel, text in SELF_TEST.items():
            (root / rel).parent.mkdir(parents=True, exist_ok=True)
            (root / rel).write_text(text)
        crate = Crate(root)
        graph = crate.edges()
        found = sorted(sorted(str(crate.files[m].relative_to(root)) for m in c) for c in sccs(graph))
    if found != [["a.rs", "b.rs"]]:
        print(f"self-test failed: expected one cycle between a.rs and b.rs, found {found}")
        return 1
    print("self-test: the one planted cycle found, nothing else")
    return 0


def main() -> int:
    if sys.argv[1:] == ["--self-test"]:
        return self_test()
    src = Path(sys.argv[1] if len(sys.argv) > 1 else Path(__file__).resolve().parent.parent / "src")
    crate = Crate(src)
    graph = crate.edges()

    def name(m: tuple[str, ...]) -> str:
        return str(crate.files[m].relative_to(src))

    failed = False
    found = []
    for comp in sorted(sccs(graph), key=lambda c: sorted(map(name, c))):
        files = frozenset(map(name, comp))
        found.append(files)
        exempt = files in EXEMPT
        cycle = a_cycle(graph, comp)
        print(f"{'exempt ' if exempt else ''}import cycle between {', '.join(sorted(files))}:")
        for a, b in zip(cycle, cycle[1:]):
            print(f"    {name(a)} uses {graph[a][b]} ({name(b)})")
        failed |= not exempt
    for files in EXEMPT:
        if files not in found:
            print(f"exemption for {', '.join(sorted(files))} matches no cycle any more: remove it")
            failed = True
    if not found:
        print(f"no import cycles between the {len(crate.files)} files of {src}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
