"""The record store's refusals (``RecordError`` of app/record_store.py) in the reader's language (issue 47): a row of
a kind the record does not keep is refused in words of the catalog; a database that cannot be written is named with
SQLite's own words, and ``commission sign`` says it in the command line's language around them."""

from __future__ import annotations

import sqlite3

import pytest

from app import cli_lang, i18n
from app.message import said
from app.record_cli import sign_record
from app.record_store import RecordError, RecordStore
from tests.recordutil import demo_runtime

pytestmark = pytest.mark.timeout(120)

DE = i18n.get("de")


@pytest.fixture
def german():
    cli_lang.set_language("de")
    yield
    cli_lang.set_language("en")


def test_a_row_of_an_unknown_kind_is_refused_in_german(tmp_path):
    store = RecordStore(tmp_path / "record.sqlite")
    try:
        with pytest.raises(RecordError) as refused:
            store.add(plant="p", device="door-1", kind="wish", user="anna", role="engineer", data={})
    finally:
        store.close()
    assert str(refused.value) == "unknown record kind 'wish'"  # the English, as the record service keeps it
    assert said(refused.value, DE) == "unbekannte Eintragsart 'wish'"


async def test_a_record_that_cannot_be_written_is_said_in_german_with_sqlites_words(tmp_path, german, monkeypatch):
    async with demo_runtime(tmp_path, ("door-2",), online=False) as runtime:
        runtime.users.add("anna", "engineer", "anna-password")

        def full(db, **row):
            raise sqlite3.OperationalError("database or disk is full")

        monkeypatch.setattr(runtime.record.store, "_append", full)
        out: list[str] = []
        assert await sign_record(runtime, user="cli:anna", role="engineer", name="Anna", comment="", out=out.append,
                                 account="anna", sign_anyway=True) == 1
        path = runtime.record.store.path
        assert out[-1] == f"commission: nicht abgezeichnet: {path}: database or disk is full", out
        assert runtime.record.problem == f"{path}: database or disk is full"
