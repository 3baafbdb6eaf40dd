"""Checks the Python package's built files before anything is installed from them (issue 23).

Usage: python3 .ci/python_dist_check.py WHEEL SDIST

The wheel: one abi3 wheel for CPython >= 3.11 (its file name and WHEEL tags), the compiled half
as `gripper_rs/_native.abi3.so`, the stubs and `py.typed` (PEP 561), both license files, and the
metadata a package index shows (name, summary, readme, license, URLs, classifiers). The sdist: what
a build from it needs (the Python project, the Rust workspace with its lock file, both crates'
sources). Prints each finding and exits 1 if any check failed, so that CI stops here.
"""

from __future__ import annotations

import email.parser
import re
import sys
import tarfile
import zipfile
from pathlib import PurePosixPath

DIST = "gripper-rs"
PACKAGE = "gripper_rs"
LICENSE = "MIT OR Apache-2.0"
LICENSE_FILES = ("LICENSE-MIT", "LICENSE-APACHE")
CLASSIFIERS = (
    "Typing :: Typed",
    "Programming Language :: Rust",
    "Programming Language :: Python :: 3 :: Only",
)

failures: list[str] = []


def check(ok: bool, what: str) -> None:
    print(("ok     " if ok else "FAILED ") + what)
    if not ok:
        failures.append(what)


def check_wheel(path: str) -> None:
    name = PurePosixPath(path).name
    # {dist}-{version}-{python}-{abi}-{platform}.whl (PEP 427): abi3 from CPython 3.11 on.
    match = re.fullmatch(rf"{PACKAGE}-([^-]+)-cp311-abi3-([^-]+)\.whl", name)
    check(match is not None, f"wheel file name {name} is {PACKAGE}-VERSION-cp311-abi3-PLATFORM")
    version = match.group(1) if match else "?"
    with zipfile.ZipFile(path) as wheel:
        files = set(wheel.namelist())
        info = f"{PACKAGE}-{version}.dist-info"

        def text(member: str) -> str:
            return wheel.read(member).decode() if member in files else ""

        for member in (
            "__init__.py",
            "_native.pyi",
            "py.typed",
            "errors.py",
            "reconnect.py",
            "_lifecycle.py",
            "wsg/__init__.py",
        ):
            check(f"{PACKAGE}/{member}" in files, f"wheel holds {PACKAGE}/{member}")
        natives = sorted(f for f in files if f.startswith(f"{PACKAGE}/_native"))
        check(
            natives == [f"{PACKAGE}/_native.abi3.so", f"{PACKAGE}/_native.pyi"],
            f"the compiled half is {PACKAGE}/_native.abi3.so, beside its stub (found {natives})",
        )
        for license_file in LICENSE_FILES:
            body = text(f"{info}/licenses/{license_file}")
            # A symlink packed as its target's name would be a few bytes, not the license.
            check(len(body) > 500, f"wheel holds {info}/licenses/{license_file} ({len(body)} bytes)")

        tags = email.parser.Parser().parsestr(text(f"{info}/WHEEL"))
        check(tags["Root-Is-Purelib"] == "false", "WHEEL: Root-Is-Purelib: false (compiled code)")
        check(
            all(t.startswith("cp311-abi3-") for t in tags.get_all("Tag") or ["none"]),
            f"WHEEL tags are cp311-abi3-* ({tags.get_all('Tag')})",
        )

        meta = email.parser.Parser().parsestr(text(f"{info}/METADATA"))
        check(meta["Name"] == DIST, f"METADATA Name: {meta['Name']} (want {DIST})")
        check(meta["Requires-Python"] == ">=3.11", f"METADATA Requires-Python: {meta['Requires-Python']}")
        check(bool(meta["Summary"]), "METADATA Summary is set")
        check(
            meta["License-Expression"] == LICENSE,
            f"METADATA License-Expression: {meta['License-Expression']} (want {LICENSE})",
        )
        check(
            sorted(meta.get_all("License-File") or []) == sorted(LICENSE_FILES),
            f"METADATA License-File: {meta.get_all('License-File')}",
        )
        classifiers = meta.get_all("Classifier") or []
        for classifier in CLASSIFIERS:
            check(classifier in classifiers, f"METADATA Classifier: {classifier}")
        urls = meta.get_all("Project-URL") or []
        check(
            bool(urls) and all(", https://" in url for url in urls),
            f"METADATA Project-URL: {urls}",
        )
        check(
            (meta["Description-Content-Type"] or "").startswith("text/markdown"),
            f"METADATA Description-Content-Type: {meta['Description-Content-Type']}",
        )
        readme = meta.get_payload()
        check(
            isinstance(readme, str) and f"pip install {DIST}" in readme,
            f"METADATA readme (python/README.md) tells `pip install {DIST}`",
        )


def check_sdist(path: str) -> None:
    with tarfile.open(path) as sdist:
        names = sdist.getnames()
    roots = {n.split("/", 1)[0] for n in names}
    check(len(roots) == 1, f"sdist has one top folder ({sorted(roots)})")
    files = {n.split("/", 1)[1] for n in names if "/" in n}
    needed = [
        "PKG-INFO",
        "pyproject.toml",
        "Cargo.toml",
        "Cargo.lock",
        "src/lib.rs",
        "python/Cargo.toml",
        "python/src/lib.rs",
        f"{PACKAGE}/__init__.py",
        f"{PACKAGE}/_native.pyi",
        f"{PACKAGE}/py.typed",
        *LICENSE_FILES,
    ]
    for member in needed:
        check(member in files, f"sdist holds {member}")
    leaked = sorted(f for f in files if f.startswith((".ci/", "fuzz/", "target/", ".git/")))
    check(not leaked, f"sdist holds no repository tools or build output ({leaked[:5]})")


def main() -> int:
    if len(sys.argv) != 3:
        print(__doc__, file=sys.stderr)
        return 2
    check_wheel(sys.argv[1])
    check_sdist(sys.argv[2])
    if failures:
        print(f"{len(failures)} check(s) of the built files failed", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
