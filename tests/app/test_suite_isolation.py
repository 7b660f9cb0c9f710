"""The suite's own isolation: every test's apps keep their data in a folder of the test's (tests/conftest.py), in
one process and in each of pytest-xdist's workers alike."""

from __future__ import annotations

import os

import conftest


def test_a_test_keeps_its_data_in_a_folder_of_its_own(tmp_path):
    assert conftest._RUN_DATA_DIR is not None, "this process does not know the run's data folder: every test shares it"
    assert os.environ["COMMISSION_DATA_DIR"] == str(tmp_path / "data")


def test_another_test_does_not_share_it(tmp_path):
    assert os.environ["COMMISSION_DATA_DIR"] == str(tmp_path / "data")
    assert os.environ["COMMISSION_DATA_DIR"] != conftest._RUN_DATA_DIR
