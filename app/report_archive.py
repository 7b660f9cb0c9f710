"""The as-left archive of a plant and ``commission report``: report.html and report.pdf in the language chosen when
they are made, the approved sets and snapshots as backup files, each checkout step's evidence file, the record's
chain and a manifest of every file's SHA-256 (checked by ``commission verify``, app/verify.py)."""

from __future__ import annotations

import argparse
import asyncio
import io
import json
import os
import tempfile
import time
import zipfile
from pathlib import Path

from app import cli_lang, i18n
from app.cli_lang import _
from app.report import altered_text, plant_content, plant_html
from app.report_evidence import can_trace, evidence_file
from app.report_pdf import plant_pdf
from app.verify import CHAIN, MANIFEST, MANIFEST_SUM, manifest_sum, seal_archive, sha256


async def write_plant(runtime, out_dir: Path, content: dict | None = None, *, user: str = "local", role: str = "engineer",
                      lang: i18n.Lang | None = None) -> dict[str, Path]:
    """report.html, report.pdf and the archive (reports, approved sets and snapshots as backup files,
    evidence traces, the record's chain and a manifest of every file's SHA-256) into ``out_dir``; the
    reports in ``lang`` (English when None), chosen when they are made."""
    content = content or await plant_content(runtime, user=user, role=role)
    snapshots = {}
    for d in content["devices"]:
        for kind in ("approved", "snapshot"):
            entry = await runtime.record.store.run(runtime.record.store.latest, runtime.record.plant, d["device"], kind)
            if entry is not None:
                snapshots[f"backups/{d['device']}-{kind}.json"] = json.dumps(_as_backup(runtime, d, entry), indent=1, ensure_ascii=False)
    chain = await runtime.record.store.run(runtime.record.store.chain_rows)
    raw = {}
    for d in content["devices"]:  # the evidence as the checkout rows hold it (the content keeps only its file names)
        for entry in await runtime.record.timeline(d["device"], ("checkout",)):
            raw[entry.id] = entry.data.get("steps", [])
    return await asyncio.to_thread(_write_files, out_dir, content, snapshots, chain, raw, lang)


def _as_backup(runtime, d: dict, entry) -> dict:
    from app.backup import make_document

    params = [{"key": k, "name": v["name"], "raw": v["raw"], "value": v["raw"], "text": v["text"], "unit": v.get("unit", ""),
               "writable": v.get("writable", False)} for k, v in entry.data["parameters"].items()]
    return make_document(runtime.plant.name, d["device"], d["type"], d["bus"], entry.data.get("identity", {}), params, entry.time,
                         user=entry.user, role=entry.role)


def _write_files(out_dir: Path, content: dict, backups: dict[str, str], chain: list[dict] | None = None,
                 raw_steps: dict[int, list] | None = None, lang: i18n.Lang | None = None) -> dict[str, Path]:
    out_dir.mkdir(parents=True, exist_ok=True)
    name = f"{content['plant']}-as-left"
    html_text = plant_html(content, lang)
    pdf = plant_pdf(content, lang)
    paths = {"html": out_dir / f"{name}.html", "pdf": out_dir / f"{name}.pdf", "zip": out_dir / f"{name}.zip"}
    _atomic(paths["html"], html_text.encode())
    _atomic(paths["pdf"], pdf)
    files: dict[str, bytes] = {f"{name}.html": html_text.encode(), f"{name}.pdf": pdf,
                               f"{name}.json": json.dumps(content, indent=1, ensure_ascii=False, default=str).encode()}
    files.update((path, text.encode()) for path, text in backups.items())
    for d in content["devices"]:
        for c in d["checkouts"]:
            for n, s in enumerate(c["steps"], 1):
                ev = (raw_steps or {}).get(c["id"], c["steps"])[n - 1].get("evidence") or s.get("evidence") or {}
                made = evidence_file(d["device"], d["bus"], c["id"], n, ev)
                if made is not None:
                    files[made[0]] = made[1]
                if ev.get("kind") == "can" and ev.get("frames"):
                    files[made[0].removesuffix(".log") + ".trc"] = can_trace(ev["frames"], ".trc", d["bus"])
    if chain is not None:
        files[CHAIN] = "".join(json.dumps(r, ensure_ascii=False, sort_keys=True) + "\n" for r in chain).encode()
    check = content.get("record_check") or {}
    manifest = {"format": 1, "plant": content["plant"], "generated": content["generated"], "tool": content.get("tool"),
                "plant_file": content.get("plant_file"), "simulated": content.get("simulated", []),
                "chain": {"rows": len(chain or []), "head": None if not chain else {"id": chain[-1]["id"], "hash": chain[-1]["hash"]}},
                "record_altered": check.get("problems", []),
                "signoff": content.get("signoff") and {k: content["signoff"].get(k) for k in ("id", "account", "name", "sha256", "row_hash")},
                "files": {path: {"sha256": sha256(data), "bytes": len(data)} for path, data in files.items()},
                "check": "commission verify ARCHIVE (app/verify.py describes every rule)"}
    manifest_bytes = json.dumps(manifest, indent=1, ensure_ascii=False, default=str).encode()
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as archive:
        archive.writestr(MANIFEST, manifest_bytes)
        archive.writestr(MANIFEST_SUM, manifest_sum(manifest_bytes))
        for path, data in files.items():
            archive.writestr(path, data)
    _atomic(paths["zip"], seal_archive(buf.getvalue()))
    return paths


def _atomic(path: Path, data: bytes) -> None:
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".part", dir=path.parent)
    with os.fdopen(fd, "wb") as handle:
        handle.write(data)
        handle.flush()
        os.fsync(handle.fileno())
    os.replace(tmp, path)


# -- CLI: commission report --plant P --out DIR ----------------------------------------------------------
def add_parser(sub) -> None:
    parser = sub.add_parser("report", help=_("write the as-left report (HTML, PDF) and archive of a plant, headless"))
    parser.add_argument("--plant", type=Path, default=None, help=_("plant file (default: the built-in demo plant)"))
    parser.add_argument("--out", type=Path, required=True, help=_("folder for the report files"))
    parser.add_argument("--no-sim", action="store_true", help=_("do not start simulated devices"))
    parser.add_argument("--wait", type=float, default=20.0, help=_("seconds to wait for the devices to come online (default 20)"))
    parser.add_argument("--data-dir", type=Path, default=None, help=_("data folder with the record (default: the per-user data folder, docs/windows-macos.md)"))
    parser.set_defaults(func=run_cli)


def run_cli(args: argparse.Namespace) -> int:
    from app.headless import load_plant_or_exit
    from app.runtime import Runtime
    from app.users import default_data_dir

    plant = load_plant_or_exit(args.plant)
    runtime = Runtime(plant, simulate=not args.no_sim, data_dir=args.data_dir or default_data_dir())

    async def main() -> dict:
        await runtime.start()
        try:
            end = time.monotonic() + args.wait
            while time.monotonic() < end and not all(s.status == "online" for s in runtime.store.devices.values()):
                await asyncio.sleep(0.2)
            content = await plant_content(runtime)
            return content, await write_plant(runtime, args.out, content, lang=cli_lang.lang())
        finally:
            await runtime.stop()

    content, paths = asyncio.run(main())
    for kind, path in paths.items():
        print(_("{kind}: {path} ({size} bytes)").format(kind=kind, path=path, size=path.stat().st_size))
    if altered_text(content):  # never passed over in silence: the report says it on its cover too
        print(_("commission report: {problem}").format(problem=altered_text(content, cli_lang.lang())))
        return 1
    return 0
