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


@pytest.fixture
def fnmpc_exe():
    exe = os.environ.get("FNMPC_EXE")
    if not exe:
        raise RuntimeError("FNMPC_EXE (the fnmpc CLI) is not set; run the tests through ctest")
    return exe
