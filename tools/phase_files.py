"""A pytest plugin for :mod:`tools.suite`: while the suite is collected once before its phases, it writes each test
file's markers to the file ``COMMISSION_SUITE_MARKS`` names, so that every phase's processes collect only the files
that hold a test of that phase (collecting the whole suite costs a process about 6 s of CPU, the real-time phase's
23 files 1.5 s, and a phase starts up to eight processes)."""

from __future__ import annotations

import json
import os

import pytest


@pytest.hookimpl(trylast=True)
def pytest_collection_modifyitems(config, items) -> None:
    target = os.environ.get("COMMISSION_SUITE_MARKS")
    if not target:
        return
    marks = [[item.nodeid.split("::")[0], sorted({mark.name for mark in item.iter_markers()})] for item in items]
    with open(target, "w", encoding="utf-8") as out:
        json.dump(marks, out)
