"""Tamper evidence of the commissioning record, checkable by anyone.

Every record row carries the SHA-256 of the row before it (``prev_hash``) and its own (``hash``)
over every field that matters: id, time, plant, device, kind, account, role, title, the stored data
(content, signer's name, comment, time of signing) and what it supersedes. Changing, replacing or
deleting a row from outside the program breaks the chain at that row, like a certificate-transparency
log; the archive carries the chain, the evidence files and a manifest of their hashes.

``commission verify ARCHIVE`` checks an archive; ``commission verify --record`` the record database
of a data folder. Both name the first row or file that differs. Nothing here needs the program's
own state: the rules are in this file (:func:`row_hash`), so a third party can check with them.
"""

from __future__ import annotations

import argparse
import hashlib
import io
import json
import sqlite3
import struct
import zipfile
import zlib
from dataclasses import dataclass, field
from pathlib import Path

from app import cli_lang
from app.cli_lang import _
from app.i18n import N_, Lang
from app.message import Message, joined, said

GENESIS = "0" * 64  # the prev_hash of the first row
HASHED = ("id", "time", "plant", "device", "kind", "user", "role", "title", "data", "supersedes", "prev_hash")
MANIFEST = "manifest.json"
MANIFEST_SUM = "manifest.sha256"
CHAIN = "record/chain.jsonl"
TRIGGERS = ("record_no_update", "record_no_delete", "record_no_replace")
DIRECTORY = N_("(the archive's directory)")  # a seal's span beside the members
SEAL_ALTERED = N_("the archive's seal (its comment) was altered or removed")


def row_hash(row: dict) -> str:
    """SHA-256 of a row: the canonical JSON (sorted keys, no spaces, UTF-8) of the fields of
    :data:`HASHED`, ``data`` as the text stored."""
    fields = {k: row.get(k) for k in HASHED}
    text = json.dumps(fields, sort_keys=True, separators=(",", ":"), ensure_ascii=False)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def content_sha256(content: dict) -> str:
    """The SHA-256 of a sign-off's frozen report content, as stored in the sign-off."""
    frozen = json.dumps(content, sort_keys=True, ensure_ascii=False, default=str)
    return hashlib.sha256(frozen.encode()).hexdigest()


def sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


@dataclass
class Check:
    """The result of a check: ``problems`` in the order found (the first names the first row or file
    that differs), ``notes`` that are no alteration (rows kept before the chain began)."""

    what: str  # what was checked: "record PATH" or "archive NAME" (a :class:`Message`)
    problems: list[str] = field(default_factory=list)  # each a :class:`Message`: English, worded in any language
    notes: list[str] = field(default_factory=list)
    rows: int = 0
    files: int = 0
    head: tuple[int, str] | None = None

    @property
    def ok(self) -> bool:
        return not self.problems

    def summary(self) -> Message:
        """Whether it is intact, in one line; the first alteration as found."""
        if self.ok:
            parts = [Message(N_("{n} record rows chained"), n=self.rows)]
            if self.files:
                parts.append(Message(N_("{n} files match the manifest"), n=self.files))
            head = Message(N_("; last row #{id}, hash {hash}"), id=self.head[0], hash=self.head[1][:16]) if self.head else ""
            return Message(N_("{what}: intact ({parts}{head})"), what=self.what, parts=joined(parts), head=head)
        return Message(N_("{what}: ALTERED: {problem}"), what=self.what, problem=self.problems[0])

    def lines(self, lang: Lang | None = None) -> list[str]:
        """The summary, every further alteration and the notes, in ``lang`` (None: English)."""
        out = [said(self.summary(), lang)]
        out += ["  " + said(Message(N_("altered: {problem}"), problem=p), lang) for p in self.problems[1:]]
        out += ["  " + said(Message(N_("note: {note}"), note=n), lang) for n in self.notes]
        return out


def legacy_digest(rows: list[dict]) -> str:
    """One SHA-256 over the rows kept before the chain began (each row's fields as :func:`row_hash` takes them)."""
    return sha256("".join(row_hash({**r, "prev_hash": None}) for r in rows).encode())


def check_chain(rows: list[dict], check: Check, head: dict | None = None) -> None:
    """Check the chain of ``rows`` (ordered by id): each row's hash, its link to the row before and
    gap-free ids; ``head`` (the last row written, as kept beside the database or in a manifest) must
    still be there with the same hash. Rows without a hash are accepted only before the first chained
    row, and only when that row (kind ``integrity``) names them and their digest."""
    legacy: list[dict] = []
    while len(legacy) < len(rows) and rows[len(legacy)].get("hash") is None and rows[len(legacy)].get("prev_hash") is None:
        legacy.append(rows[len(legacy)])
    chained = rows[len(legacy):]
    if legacy:
        start = chained[0] if chained else None
        try:
            named = json.loads(start["data"]).get("legacy") if start and start.get("kind") == "integrity" else None
        except (TypeError, ValueError):
            named = None
        if named and named.get("rows") == len(legacy) and named.get("sha256") == legacy_digest(legacy):
            check.notes.append(Message(N_("{n} rows were recorded before the record kept its chain; row #{id} holds their "
                                          "digest, which matches"), n=len(legacy), id=start["id"]))
        elif named:
            check.problems.append(Message(N_("rows #{first} to #{last}, recorded before the chain began, were changed: their "
                                             "digest is not the one row #{id} holds"),
                                          first=legacy[0]["id"], last=legacy[-1]["id"], id=start["id"]))
        else:
            check.problems.append(Message(N_("row #{id} ({kind} {title!r}) has no hash: it was written or replaced from outside "
                                             "the program"), id=legacy[0]["id"], kind=legacy[0].get("kind"),
                                          title=legacy[0].get("title")))
    before = None
    for row in chained:
        check.rows += 1
        rid = row.get("id")
        if before is not None and rid != before["id"] + 1:
            if rid == before["id"] + 2:
                check.problems.append(Message(N_("row #{missing} is missing (deleted from outside the program): row #{id} "
                                                 "follows #{before}"), missing=before["id"] + 1, id=rid, before=before["id"]))
            else:
                check.problems.append(Message(N_("row #{first} to #{last} is missing (deleted from outside the program): row "
                                                 "#{id} follows #{before}"), first=before["id"] + 1, last=rid - 1, id=rid,
                                              before=before["id"]))
        if row.get("hash") != row_hash(row):
            check.problems.append(Message(N_("row #{id} ({kind} {title!r}) was changed after it was written: its content no "
                                             "longer matches its hash"), id=rid, kind=row.get("kind"), title=row.get("title")))
        elif before is not None and rid == before["id"] + 1 and row.get("prev_hash") != before["hash"]:
            check.problems.append(Message(N_("row #{before} was changed or replaced: row #{id} no longer links to it"),
                                          before=before["id"], id=rid))
        elif before is None and row.get("prev_hash") != GENESIS:
            check.problems.append(Message(N_("row #{id} does not start the chain: the rows before it were deleted"), id=rid))
        before = row
    if before is not None:
        check.head = (before["id"], before["hash"])
    if head:
        by_id = {r.get("id"): r for r in rows}
        kept = by_id.get(head.get("id"))
        if kept is None:
            check.problems.append(Message(N_("row #{id}, the last one written, is missing (deleted from outside the program)"),
                                          id=head.get("id")))
        elif kept.get("hash") != head.get("hash"):
            check.problems.append(Message(N_("row #{id}, the last one written, was changed or replaced"), id=head.get("id")))


def check_signoffs(rows: list[dict], check: Check) -> None:
    """Each sign-off's stored SHA-256 matches its frozen content; a protection the program found
    removed from outside (an ``integrity`` row) stays an alteration of the record for ever."""
    for row in rows:
        if row.get("kind") == "integrity":
            try:
                removed = json.loads(row["data"]).get("removed_triggers")
            except (TypeError, ValueError):
                removed = None
            if removed:
                check.problems.append(Message(N_("row #{id}: the program found the record's protection ({triggers}) removed from "
                                                 "outside the program; rows may have been changed or deleted then"),
                                              id=row.get("id"), triggers=", ".join(removed)))
        if row.get("kind") != "signoff":
            continue
        try:
            data = json.loads(row["data"])
        except (TypeError, ValueError):
            check.problems.append(Message(N_("row #{id} (sign-off) cannot be read"), id=row.get("id")))
            continue
        if "content" in data and data.get("sha256") != content_sha256(data["content"]):
            check.problems.append(Message(N_("row #{id} (sign-off by {name}): the signed content does not match its SHA-256"),
                                          id=row.get("id"), name=data.get("name")))


# -- the record database -------------------------------------------------------------------------
def read_rows(db: sqlite3.Connection) -> list[dict]:
    cols = [c[1] for c in db.execute("PRAGMA table_info(record)")]
    names = [c for c in ("id", "time", "plant", "device", "kind", "user", "role", "title", "data", "supersedes", "prev_hash", "hash")
             if c in cols]
    return [dict(zip(names, r)) for r in db.execute(f"SELECT {', '.join(names)} FROM record ORDER BY id")]


def head_path(db_path: Path) -> Path:
    return db_path.with_name(db_path.name + ".head")


def read_head(db_path: Path) -> dict | None:
    try:
        return json.loads(head_path(db_path).read_text())
    except (OSError, ValueError):
        return None


def check_database(path: Path) -> Check:
    """Check a record database read-only (another program may have it open)."""
    check = Check(Message(N_("record {path}"), path=path))
    if not path.exists():
        check.problems.append(Message(N_("{path} does not exist"), path=path))
        return check
    db = sqlite3.connect(f"file:{path}?mode=ro", uri=True)
    try:
        triggers = {r[0] for r in db.execute("SELECT name FROM sqlite_master WHERE type = 'trigger'")}
        rows = read_rows(db)
    finally:
        db.close()
    check_chain(rows, check, read_head(path))
    for name in TRIGGERS:
        if name not in triggers:
            check.problems.append(Message(N_("the record's protection {name} was removed from outside the program"), name=name))
    check_signoffs(rows, check)
    return check


# -- the archive ---------------------------------------------------------------------------------
def manifest_sum(manifest: bytes) -> bytes:
    return f"{sha256(manifest)}  {MANIFEST}\n".encode()


# what the zip reader (and the seal's JSON) raise on altered bytes: its BadZipFile, OSError and EOFError; ValueError
# (a name or comment that does not decode among them); struct.error for a cut header; zlib's error for broken deflate
# data; NotImplementedError for a compression method it does not know; RecursionError for JSON nested too deep
ALTERED: tuple[type[Exception], ...] = (zipfile.BadZipFile, OSError, EOFError, ValueError, struct.error, zlib.error,
                                        NotImplementedError, RecursionError)


def _eocd(data: bytes) -> int:
    """Offset of the zip's end-of-central-directory record (-1: none)."""
    return data.rfind(b"PK\x05\x06", max(0, len(data) - 22 - 65535))


def _spans(data: bytes, end: int) -> list[tuple[str, int, int]]:
    """Each member's stored bytes (local header and data) as (name, start, end), and the central directory."""
    archive = zipfile.ZipFile(io.BytesIO(data))
    cd_start = int.from_bytes(data[end + 16:end + 20], "little")
    infos = sorted(archive.infolist(), key=lambda i: i.header_offset)
    starts = [i.header_offset for i in infos] + [cd_start]
    return [(i.filename, starts[n], starts[n + 1]) for n, i in enumerate(infos)] + [(DIRECTORY, cd_start, end + 20)]


def seal_archive(data: bytes) -> bytes:
    """The archive with a comment holding the SHA-256 of each member's stored bytes and of every byte
    of the archive but the comment with those: one byte changed anywhere (also in a header, or in padding that does not change
    what unpacks) is found, and the member it lies in named."""
    end = _eocd(data)
    spans = _spans(data, end)
    placeholder = {"sha256": "0" * 64, "spans": {name: "0" * 64 for name, _a, _b in spans}}
    length = len(json.dumps(placeholder, separators=(",", ":")).encode())
    head = data[:end + 20] + length.to_bytes(2, "little")
    sealed = {name: sha256(data[a:b]) for name, a, b in spans}
    comment = {"sha256": sha256(head + json.dumps(sealed, separators=(",", ":")).encode()), "spans": sealed}
    return head + json.dumps(comment, separators=(",", ":")).encode()


def _check_seal(data: bytes, check: Check) -> None:
    end = _eocd(data)
    if end < 0:
        check.problems.append(Message(N_("the archive's directory is missing: it was altered")))
        return
    try:
        seal = json.loads(data[end + 22:])
        spans = _spans(data, end)
    except ALTERED:  # an altered directory breaks the zip reader in many ways
        check.problems.append(Message(SEAL_ALTERED))
        return
    if isinstance(seal, dict) and sha256(data[:end + 22] + json.dumps(seal.get("spans"), separators=(",", ":")).encode()) == seal.get("sha256"):
        return
    if not isinstance(seal, dict) or not isinstance(seal.get("spans"), dict):
        check.problems.append(Message(SEAL_ALTERED))
        return
    for name, a, b in spans:
        if seal.get("spans", {}).get(name) != sha256(data[a:b]):
            check.problems.append(Message(N_("file {name} was altered: its stored bytes are not the ones sealed when the archive "
                                             "was made"), name=name) if name != DIRECTORY else
                                  Message(N_("{name} was altered"), name=Message(DIRECTORY)))
            return
    check.problems.append(Message(N_("the archive was altered: its bytes are not the ones sealed when it was made")))


def check_archive(path: Path) -> Check:
    """Check an as-left archive: its manifest, every file against the manifest, the record chain it
    carries, the sign-offs, and that the chain it carries is the one the manifest names."""
    check = Check(Message(N_("archive {name}"), name=path.name))
    try:
        data = path.read_bytes()
        archive = zipfile.ZipFile(io.BytesIO(data))
        names = archive.namelist()
    except ALTERED as exc:  # an altered archive breaks the zip reader in many ways
        check.problems.append(Message(N_("{path} is no readable archive ({error}): it was altered or is not an as-left archive"),
                                      path=path, error=exc))
        return check
    sealed = Check(check.what)
    _check_seal(data, sealed)
    contents: dict[str, bytes] = {}
    for name in names:
        try:
            contents[name] = archive.read(name)
        except (zipfile.BadZipFile, OSError, EOFError, ValueError) as exc:  # a CRC that no longer matches, broken data
            check.problems.append(Message(N_("file {name} was altered: its bytes no longer match the archive's check sum ({error})"),
                                          name=name, error=exc))
        except (zlib.error, struct.error, NotImplementedError) as exc:  # broken deflate data, a cut header, an odd method
            check.problems.append(Message(N_("file {name} was altered: it cannot be unpacked ({error})"), name=name, error=exc))
    if MANIFEST not in contents or MANIFEST_SUM not in contents:
        if MANIFEST not in names or MANIFEST_SUM not in names:
            check.problems.append(Message(N_("the archive has no {manifest} and {sum}: it is no verifiable as-left archive"),
                                          manifest=MANIFEST, sum=MANIFEST_SUM))
        return check
    if contents[MANIFEST_SUM] != manifest_sum(contents[MANIFEST]):
        check.problems.append(Message(N_("file {name} was altered: its SHA-256 is not the one in {sum}"), name=MANIFEST,
                                      sum=MANIFEST_SUM))
        return check
    try:
        manifest = json.loads(contents[MANIFEST])
    except ValueError:
        check.problems.append(Message(N_("file {name} cannot be read"), name=MANIFEST))
        return check
    listed: dict[str, dict] = manifest.get("files", {})
    for name in sorted(listed, key=lambda n: (n != CHAIN, n)):
        if name not in names:
            check.problems.append(Message(N_("file {name} is missing from the archive"), name=name))
        elif name in contents and sha256(contents[name]) != listed[name].get("sha256"):
            check.problems.append(Message(N_("file {name} was altered: its SHA-256 is not the one in the manifest"), name=name))
        else:
            check.files += 1
    for name in names:
        if name not in listed and name not in (MANIFEST, MANIFEST_SUM):
            check.problems.append(Message(N_("file {name} was added: it is not in the manifest"), name=name))
    if CHAIN in contents:
        rows = [json.loads(line) for line in contents[CHAIN].decode("utf-8", "replace").splitlines() if line.strip()]
        chain = Check(check.what)
        check_chain(rows, chain, manifest.get("chain", {}).get("head"))
        check_signoffs(rows, chain)
        check.problems += [Message(N_("in {file}: {problem}"), file=CHAIN, problem=p) for p in chain.problems]
        check.notes += chain.notes
        check.rows, check.head = chain.rows, chain.head
    check.problems += [p for p in sealed.problems if p not in check.problems and not any(
        p.split(" was altered")[0] == q.split(" was altered")[0] for q in check.problems)]
    if manifest.get("simulated"):
        check.notes.append(Message(N_("made on simulated devices: {devices}"), devices=", ".join(manifest["simulated"])))
    for problem in manifest.get("record_altered", []):  # as the manifest holds it: the English of when it was made
        check.notes.append(Message(N_("the record was already altered when the archive was made: {problem}"), problem=problem))
    return check


# -- CLI: commission verify ------------------------------------------------------------------------
def add_parser(sub) -> None:
    parser = sub.add_parser("verify", help=_("check an as-left archive (or the record database) for alterations; "
                                           "exit code 0 only when intact"))
    parser.add_argument("archive", nargs="?", type=Path, help=_("the as-left archive (.zip) to check"))
    parser.add_argument("--record", action="store_true", help=_("check the record database of the data folder instead"))
    parser.add_argument("--data-dir", type=Path, default=None, help=_("data folder with the record (default: the per-user data folder, docs/windows-macos.md)"))
    parser.set_defaults(func=run_cli)


def run_cli(args: argparse.Namespace) -> int:
    if args.archive is None and not args.record:
        print(_("commission verify: name an archive (commission verify PLANT-as-left.zip) or --record for the data folder's record"))
        return 2
    if args.record:
        from app.users import default_data_dir

        check = check_database((args.data_dir or default_data_dir()) / "record.sqlite")
    else:
        check = check_archive(args.archive)
    for line in check.lines(cli_lang.lang()):
        print(line)
    return 0 if check.ok else 1
