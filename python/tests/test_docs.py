"""Docs in the IDE (issue 32): every public class, method and property of the stub has a
docstring (an editor shows it on hover), and so has every public name of the Python modules."""

from __future__ import annotations

import ast
import importlib
import inspect
from pathlib import Path

import pytest

import gripper_rs

MODULES = [
    "gripper_rs",
    "gripper_rs.errors",
    "gripper_rs.reconnect",
    "gripper_rs.wsg",
    "gripper_rs.wsg.text",
    "gripper_rs.wsg.sim",
    "gripper_rs.griplink",
    "gripper_rs.griplink.sim",
    "gripper_rs.smartgrasp",
    "gripper_rs.smartgrasp.sim",
    "gripper_rs.aio",
]


def undocumented(node: ast.AST, prefix: str = "") -> list[str]:
    missing = []
    for child in getattr(node, "body", []):
        if isinstance(child, (ast.ClassDef, ast.FunctionDef)) and not child.name.startswith("_"):
            name = prefix + child.name
            # The protocol namespaces (`class wsg:`) only group the classes.
            grouping = isinstance(child, ast.ClassDef) and prefix == "" and child.name.islower()
            if ast.get_docstring(child) is None and not grouping:
                missing.append(name)
            if isinstance(child, ast.ClassDef):
                missing += undocumented(child, name + ".")
        elif isinstance(child, ast.ClassDef) and child.name.startswith("_"):
            missing += undocumented(child, prefix + child.name + ".")
    return missing


def test_every_public_stub_item_has_a_docstring() -> None:
    # The stub the wheel installs, next to the package.
    stub = Path(gripper_rs.__file__).parent / "_native.pyi"
    assert undocumented(ast.parse(stub.read_text())) == []


@pytest.mark.parametrize("module", MODULES)
def test_every_public_name_has_a_docstring(module: str) -> None:
    mod = importlib.import_module(module)
    assert inspect.getdoc(mod)
    missing = [
        name
        for name in getattr(mod, "__all__", [])
        if not inspect.ismodule(getattr(mod, name))
        and not isinstance(getattr(mod, name), (int, str))
        and not inspect.getdoc(getattr(mod, name))
    ]
    assert missing == []
