# SPDX-License-Identifier: BSD-3-Clause
"""Shared paths of the Python tests (ctest sets FNMPC_SOURCE_DIR and FNMPC_EXE)."""
import os

import pytest

SOURCE_DIR = os.environ.get(
    "FNMPC_SOURCE_DIR", os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..")))


@pytest.fixture
def triangle():
    return os.path.join(SOURCE_DIR, "config", "scenarios", "triangle.yaml")


@pytest.fixture
def vehicle_file():
    return os.path.join(SOURCE_DIR, "config", "vehicles", "storm-drone-4.yaml")


def fnmpc_exe():
    """The fnmpc CLI: $FNMPC_EXE (ctest sets it), else the one of the build tree the module
    was imported from (<build>/python/fnmpc -> <build>/apps/fnmpc/fnmpc)."""
    exe = os.environ.get("FNMPC_EXE")
    if not exe:
        import fnmpc
        exe = os.path.join(os.path.dirname(fnmpc.__file__), "..", "..", "apps", "fnmpc", "fnmpc")
    if not os.access(exe, os.X_OK):
        raise RuntimeError(f"fnmpc CLI not found at {exe}; set FNMPC_EXE")
    return os.path.abspath(exe)
