"""The commissioning record without a browser: ``commission approve``, ``commission checkout``,
``commission sign`` and ``commission verify`` (app/verify.py).

An approval and a sign-off name an engineer account (``--account NAME``, its password asked as at a
login): who approved and who signed is an account, not only a typed name.

Each command starts the plant (with its simulated devices unless ``--no-sim``), waits for the
devices to come online and acts through the same record service as the record page
(``runtime.record``, app/record.py): the same checkout runner (app/checkout.py) and the worker's gate, the same role
checks. The CLI user (``cli:<login>``) acts with the engineer role; questions of a checkout are
asked on standard input (``--answer ask``) or answered yes by the CLI user (``--answer yes``), and
every answer is recorded with who gave it.

Headless runs are no way around the operator (issue 40): ``--answer yes`` answers only for simulated
devices (twins of this run). A checkout of real equipment asks every question of the person at the
terminal (:class:`app.headless.TerminalPerson`: yes is SPACE held, and the key held is the run's dead-man:
released, what moves stops within the dead-man bound); without a terminal such a run refuses to start.
"""

from __future__ import annotations

import argparse
import asyncio
import inspect
import sys
import time
import uuid
from pathlib import Path
from typing import Any

from app import cli_lang
from app.checkout import StepFailed, checkout_module
from app.cli_lang import _
from app.i18n import N_
from app.message import Message, message_of, said
from app.record_store import RecordError
from devices.errors import CommissionError

SIGNER_ROLE = N_("commissioning engineer")  # offered in the reader's language; the record keeps what was signed with


# -- shared -------------------------------------------------------------------------------------
def _said(text: object) -> str:
    """A refusal, a finding or an error (a :class:`Message`, or one an error carries) in the command line's language."""
    return said(text, cli_lang.lang())


def _common(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--plant", type=Path, default=None, help=_("plant file (default: the built-in demo plant)"))
    parser.add_argument("--no-sim", action="store_true", help=_("do not start simulated devices"))
    parser.add_argument("--wait", type=float, default=20.0, help=_("seconds to wait for the devices to come online (default 20)"))
    parser.add_argument("--data-dir", type=Path, default=argparse.SUPPRESS,
                        help=_("data folder with the record (default: the per-user data folder, docs/windows-macos.md)"))


def _account(parser: argparse.ArgumentParser, account_help: str) -> None:
    parser.add_argument("--account", required=True, metavar="NAME", help=account_help)


def _devices(parser: argparse.ArgumentParser, device_help: str, all_help: str) -> None:
    parser.add_argument("--device", action="append", default=[], metavar="NAME", help=device_help)
    parser.add_argument("--all", action="store_true", help=all_help)


def add_parsers(sub) -> None:
    approve = sub.add_parser("approve", help=_("store the approved parameter set of devices as read now, headless"))
    _common(approve)
    _devices(approve, _("device to approve (repeatable)"), _("approve every device of the plant"))
    _account(approve, _("the engineer account that approves (its password is asked on the terminal, or read from "
                        "standard input when that is no terminal)"))
    approve.set_defaults(func=run_approve)

    checkout = sub.add_parser("checkout", help=_("run the declared checkout of devices, headless; exit code 0 only when all passed"))
    _common(checkout)
    _devices(checkout, _("device to check out (repeatable)"), _("check out every device of the plant"))
    checkout.add_argument("--answer", choices=["yes", "ask"], default=None,
                          help=_("questions to a person: ask on standard input (default when it is a terminal) or "
                               "answer yes, recorded as answered by the CLI user; yes answers for simulated devices "
                               "only: real equipment is asked of the person at the terminal, who holds SPACE while "
                               "it moves (without a terminal such a run does not start)"))
    checkout.add_argument("--set", action="append", default=[], metavar="DEVICE:KEY=VALUE",
                          help=_("a checkout setting of one device, e.g. lift:distance_mm=10 (repeatable)"))
    checkout.add_argument("--sim-action", action="append", default=[], metavar="DEVICE:ACTION[:K=V,...]",
                          help=_("before the checkouts, run a declared control of a simulated device's twin (a fault "
                               "to see a step fail, e.g. 'heater-hm:blow fuse:channel=1'); simulation only"))
    checkout.set_defaults(func=run_checkout)

    sign = sub.add_parser("sign", help=_("sign the as-left record of the plant (or of one device), headless"))
    _common(sign)
    sign.add_argument("--name", required=True, help=_("the name of the person signing"))
    sign.add_argument("--comment", default="", help=_("free comment of the sign-off"))
    sign.add_argument("--signer-role", default=_(SIGNER_ROLE), help=_("the signer's role as written in the record (default: {role})").format(role=_(SIGNER_ROLE)))
    sign.add_argument("--device", default=None, metavar="NAME", help=_("sign this device's record instead of the plant's"))
    _account(sign, _("the engineer account that signs (its password is asked on the terminal, or read from "
                     "standard input when that is no terminal)"))
    sign.add_argument("--yes", action="store_true", help=_("sign even when devices have no checkout, a failed one or "
                                                         "settings not approved (they are listed either way)"))
    sign.set_defaults(func=run_sign)

    from app import verify

    verify.add_parser(sub)  # commission verify ARCHIVE | --record: the chain, every evidence file and the sign-off


def _cli_user() -> str:
    from app.headless import cli_user

    return cli_user()


def read_password(account: str) -> str:
    """The account's password: asked on the terminal, or the first line of standard input."""
    import getpass

    if sys.stdin is not None and sys.stdin.isatty():
        return getpass.getpass(_("password of {account}: ").format(account=account))
    return (sys.stdin.readline() if sys.stdin is not None else "").rstrip("\n")


async def login_account(runtime, account: str, password: str, *, out=print) -> str | None:
    """The named engineer account for a sign-off or an approval, checked as a login (throttled and
    audited like the web login); None after saying why not."""
    from app.auth import check_login

    if not runtime.users.has_engineer():
        out(_("commission: there is no engineer account yet: create one with 'commission user add NAME --role engineer' "
              "and give it with --account NAME"))
        return None
    user, words = await check_login(throttle=runtime.login_throttle, users=runtime.users, audit=runtime.audit, typed=account,
                                    secret=password, address="command line", via="cli")
    if user is None:
        out(_("commission: {words} for account {account}: nothing was signed or approved").format(words=_said(words), account=repr(account)))
        return None
    if user.role != "engineer":
        out(_("commission: {account} has the {role} role: only an engineer account signs or approves").format(account=account, role=_(user.role)))
        return None
    return user.name


def _chosen(runtime, args) -> list[str]:
    names = list(runtime.plant.devices)
    if args.all or not args.device:
        return names
    unknown = [n for n in args.device if n not in runtime.plant.devices]
    if unknown:
        raise SystemExit(_("commission: no device {devices} in plant {plant} (devices: {known})").format(
            devices=", ".join(unknown), plant=runtime.plant.name, known=", ".join(names)))
    return list(dict.fromkeys(args.device))


async def _wait_online(runtime, names: list[str], wait_s: float) -> None:
    end = time.monotonic() + wait_s
    while time.monotonic() < end and not all(runtime.store.devices[n].status == "online" for n in names):
        await asyncio.sleep(0.2)


def _run_plant(args, work) -> int:
    """Start the plant, wait for the chosen devices, run ``work(runtime, names)`` and stop."""
    from app.headless import load_plant_or_exit
    from app.runtime import Runtime
    from app.users import default_data_dir

    plant = load_plant_or_exit(args.plant)
    data_dir = args.data_dir or default_data_dir()  # the top-level --data-dir, None unless given
    runtime = Runtime(plant, simulate=not args.no_sim, data_dir=data_dir)

    async def main() -> int:
        await runtime.start()
        try:
            names = _chosen(runtime, args)
            await _wait_online(runtime, names, args.wait)
            return await work(runtime, names)
        finally:
            await runtime.stop()

    return asyncio.run(main())


# -- approve ------------------------------------------------------------------------------------
async def approve_devices(runtime, names: list[str], *, user: str, role: str, out=print, account: str = "") -> int:
    from app.backup import nothing_to_back_up

    failures = 0
    for name in names:
        state = runtime.store.devices[name]
        reason = await nothing_to_back_up(runtime.worker.adapters[name])
        if reason:
            out(_("{name}: skipped: {reason}").format(name=name, reason=_said(reason)))
            continue
        if state.status != "online":
            out(_("{name}: not answering ({error}): not approved").format(name=name, error=_said(state.last_error or _("no answer"))))
            failures += 1
            continue
        try:
            entry_id = await runtime.record.approve(name, user=user, role=role, account=account)
        except PermissionError as exc:
            out(f"commission: {_said(exc)}")
            return 1
        except (CommissionError, OSError) as exc:  # said, and the exit code says it
            out(_("{name}: not approved: {error}").format(name=name, error=_said(exc)))
            failures += 1
            continue
        count = len(runtime.record.approved.get(name, {}))
        out(_("{name}: approved set stored (record {id}, {count} parameters)").format(name=name, id=entry_id, count=count))
    return 0 if failures == 0 else 1


def run_approve(args) -> int:
    password = read_password(args.account)

    async def work(runtime, names: list[str]) -> int:
        account = await login_account(runtime, args.account, password)
        if account is None:
            return 1
        return await approve_devices(runtime, names, user=_cli_user(), role="engineer", account=account)

    return _run_plant(args, work)


# -- checkout -----------------------------------------------------------------------------------
TOGGLE = "toggle "  # a twin's action that toggles an input ("toggle E1", "toggle door")


def _answerer(mode: str | None, user: str, out, runtime=None, device: str = ""):
    """The ``ask`` of a CLI run: answered yes (recorded as the CLI user's answer), asked on stdin, or none.

    With ``--answer yes`` on a simulated device, a request to act ("Toggle E1 now ...") is carried out on
    the twin through its declared control (audited as a simulation action, as the page's sim card does)."""
    if mode == "yes":
        async def yes(question: str) -> bool:
            out(_("    ? {question} -> yes (answered by {user} with --answer yes)").format(question=_said(question), user=user))
            controls = runtime.sim_controls(device) if runtime is not None else None
            words = question.split()
            if controls is not None and len(words) > 1 and words[0] == "Toggle":
                action = f"toggle {words[1]}"
                if any(a.name == action for a in controls.actions):
                    out("      " + _said(await sim_action(runtime, f"{device}:{action}", user=user, role="engineer")))
            return True
        return yes
    if mode == "ask":
        async def ask(question: str) -> bool:
            while True:
                try:
                    line = await asyncio.to_thread(input, _("    ? {question} [yes/no] ").format(question=_said(question)))
                except EOFError:
                    raise StepFailed(Message(N_("{question} - no answer (standard input closed)"), question=question)) from None
                word = line.strip().lower()
                if word in ("y", "yes", "j", "ja"):  # either language's yes and no
                    return True
                if word in ("n", "no", "nein"):
                    return False
                print(_("    please answer yes or no"), flush=True)
        return ask

    async def nobody(question: str) -> bool:
        raise StepFailed(Message(N_("{question} - nobody to ask (standard input is no terminal: use --answer ask or --answer "
                                    "yes)"), question=question))
    return nobody


def _step_line(r) -> str:
    from app.report import recorded, with_unit

    lang = cli_lang.lang()
    line = f"  [{_(r.status)}] {_said(r.name)}"
    if r.ended and r.started:
        line += f" ({lang.number(r.ended - r.started, 1, group=False)} s)"
    if r.reason:
        line += f": {_said(r.reason)}"
    elif r.values:
        line += ": " + "; ".join(f"{_said(v['name'])} {lang.numbers_in(with_unit(recorded(v['value'], {}, lang), v['unit']))}"
                                 for v in r.values[:4])
    return line


def _settings(specs: list[str], device: str, module) -> dict[str, Any]:
    settings: dict[str, Any] = {}
    defaults = module.SETTINGS
    for spec in specs:
        name, _sep, rest = spec.partition(":")
        key, eq, value = rest.partition("=")
        if not eq or not key:
            raise SystemExit(_("commission: --set {spec}: expected DEVICE:KEY=VALUE").format(spec=repr(spec)))
        if name != device:
            continue
        if key not in defaults:
            raise SystemExit(_("commission: --set {spec}: the {device} checkout has no setting {key} (settings: {known})").format(
                spec=repr(spec), device=device, key=repr(key), known=", ".join(defaults)))
        kind = type(defaults[key])
        try:
            settings[key] = (value.lower() in ("1", "true", "yes")) if kind is bool else kind(value)
        except ValueError:
            raise SystemExit(_("commission: --set {spec}: {value} is no {kind}").format(spec=repr(spec), value=repr(value),
                                                                                         kind=kind.__name__)) from None
    return settings


async def sim_action(runtime, spec: str, *, user: str, role: str) -> Message:
    """Run ``DEVICE:ACTION[:K=V,...]`` on a simulated twin through the worker's gate (audited as the page's sim card);
    what was done, as the audit row says it (a toggle of an input, a checkout's request to act, in the reader's words)."""
    device, _sep, rest = spec.partition(":")
    action, _sep, arg_text = rest.partition(":")
    controls = runtime.sim_controls(device) if device in runtime.store.devices else None
    if controls is None:
        raise ValueError(Message(N_("--sim-action {spec}: {device} is no simulated device of this plant"), spec=repr(spec),
                                 device=repr(device)))
    args: dict[str, Any] = {}
    for item in filter(None, (a.strip() for a in arg_text.split(","))):
        key, _sep, value = item.partition("=")
        args[key] = value.lower() in ("1", "on", "true", "yes") if value.lower() in ("on", "off", "true", "false") else int(value, 0)
    describe = controls.describe(action, args)

    async def act() -> str:
        result = controls.invoke(action, args)
        if inspect.isawaitable(result):
            await result
        return ""

    await runtime.worker.gate.run(act, device=device, role=role, user=user, describe=f"simulation: {describe}", kind="system")
    if describe == action and action.startswith(TOGGLE):  # "toggle E1": what a checkout's "Toggle E1 now ..." asks for
        return Message(N_("{device}: simulation: toggle {input}"), device=device, input=action.removeprefix(TOGGLE))
    return Message(N_("{device}: simulation: {action}"), device=device, action=describe)


def real_without_person(real: list[str]) -> str:
    """Why a run with real equipment does not start without a person at a terminal, in the command line's language."""
    return cli_lang.lang().ngettext(
        "commission: not started: {devices} is real equipment (not a twin of this run): a checkout moves it or switches "
        "its mains outputs, so each of its questions is asked of a person at a terminal who holds SPACE while it moves "
        "(the run's dead-man). --answer yes answers only for simulated devices. Run 'commission checkout' from a "
        "terminal, or the checkout from the device's record page.",
        "commission: not started: {devices} are real equipment (not twins of this run): a checkout moves them or switches "
        "their mains outputs, so each of its questions is asked of a person at a terminal who holds SPACE while they move "
        "(the run's dead-man). --answer yes answers only for simulated devices. Run 'commission checkout' from a "
        "terminal, or the checkout from the devices' record pages.", len(real)).format(devices=", ".join(real))


RESULT_WORDS = (N_("not run"),)  # a result the summary names beside the runs' own (passed, failed ...)


def real_devices(runtime, names: list[str]) -> list[str]:
    """The devices of ``names`` that are real equipment (not twins of this run's simulated plant)."""
    from app.headless import simulated

    return [n for n in names if not simulated(runtime, n)]


async def checkout_devices(runtime, names: list[str], *, user: str, role: str, answer: str | None,
                           settings: list[str] = (), sim_actions: list[str] = (), out=print, person=None) -> int:
    """Run each device's declared checkout in turn; 0 when every one passed, else 1 (2: not started).

    ``person``: the person at the terminal (:class:`app.headless.TerminalPerson`) who answers for real
    equipment and whose held key is the dead-man of its runs; without one a run with real equipment
    does not start."""
    real = real_devices(runtime, names)
    if real and person is None:
        out(real_without_person(real))
        return 2
    for spec in sim_actions:
        try:
            out(_said(await sim_action(runtime, spec, user=user, role=role)))
        except (CommissionError, LookupError, ValueError) as exc:  # a refused action, a spec naming none
            out(f"commission: {_said(exc)}")
            return 2
        await asyncio.sleep(0.5)  # the next poll carries the fault
    results: list[tuple[str, str, str, float | None]] = []
    for name in names:
        state = runtime.store.devices[name]
        module = checkout_module(state.type)
        if module is None:
            out(_("{name}: the {type} type declares no checkout").format(name=name, type=state.type))
            results.append((name, "none", Message(N_("no checkout declared")), None))
            continue
        if state.status != "online":
            reason = Message(N_("not answering ({error})"), error=state.last_error or Message(N_("no answer")))
            out(_("{name}: {title}: not run: {reason}").format(name=name, title=_said(module.TITLE), reason=_said(reason)))
            results.append((name, "not run", reason, None))
            continue
        options: dict[str, Any] = {}
        if name in real:  # the person answers, and their held key is the session's dead-man (the run does not beat)
            ask = person.ask
            options["session"] = person.session
            if answer == "yes":
                out(_("{name}: real equipment: --answer yes does not answer for it; the questions are yours").format(name=name))
        elif person is not None and answer != "yes":  # the terminal reads keys for the person: ask there too
            ask = person.ask
        else:
            ask = _answerer(answer, user, out, runtime, name)
        try:
            run = runtime.record.new_run(name, user=user, role=role, ask=ask, settings=_settings(list(settings), name, module),
                                         **options)
        except (CommissionError, LookupError, ValueError) as exc:  # running already, settings its steps refuse
            out(f"{name}: {_said(exc)}")
            results.append((name, "not run", message_of(exc), None))
            continue
        out(_("{name} ({type}): {title}, {n} steps").format(name=name, type=state.type, title=_said(module.TITLE), n=len(run.results)))
        shown: dict[int, str] = {}

        def progress(run=run, shown=shown) -> None:
            for i, r in enumerate(run.results):
                if r.status in ("pending", "running") or shown.get(i) == r.status:
                    continue
                shown[i] = r.status
                out(_step_line(r))

        run.listeners.append(progress)
        try:
            result = await run.run()
        except PermissionError as exc:
            out(f"commission: {_said(exc)}")
            return 1
        line = _("{name}: {status} in {duration} s").format(name=name, status=_(result["status"]), duration=result["duration_s"])
        if result["reason"]:
            line += f": {_said(result['reason'])}"
        out(line + (_(" (record {id})").format(id=result.get("record_id")) if result.get("record_id") else ""))
        results.append((name, result["status"], result["reason"], result["duration_s"]))
    passed = sum(s == "passed" for _n, s, _r, _d in results)
    out(_("{passed} of {n} checkouts passed").format(passed=passed, n=len(results)))
    for n, s, r, _d in results:
        if s != "passed":
            out(f"  {n}: {_(s)}" + (f": {_said(r)}" if r else ""))
    return 0 if results and passed == len(results) else 1


def run_checkout(args) -> int:
    from app.headless import TerminalPerson, TtyKeys, terminal_present

    terminal = terminal_present()
    answer = args.answer or ("ask" if terminal else None)

    def out(text: str) -> None:
        print(text, flush=True)

    if not terminal:  # refuse before anything connects to a real bus
        from app.headless import load_plant_or_exit

        plant = load_plant_or_exit(args.plant)
        chosen = [n for n in plant.devices if args.all or not args.device or n in args.device]
        real = [n for n in chosen if args.no_sim or not plant.buses[plant.devices[n].bus].simulated]
        if real:
            out(real_without_person(real))
            return 2

    async def work(runtime, names: list[str]) -> int:
        person = None
        if terminal and real_devices(runtime, names):
            person = TerminalPerson(runtime.worker, f"cli-checkout-{uuid.uuid4().hex[:8]}", TtyKeys(), out)
            person.start()
        try:
            return await checkout_devices(runtime, names, user=_cli_user(), role="engineer", answer=answer,
                                          settings=args.set, sim_actions=args.sim_action, out=out, person=person)
        finally:
            if person is not None:
                person.stop()

    return _run_plant(args, work)


# -- sign ---------------------------------------------------------------------------------------
async def sign_record(runtime, *, user: str, role: str, name: str, comment: str, signer_role: str = SIGNER_ROLE,
                      device: str | None = None, out=print, account: str = "", sign_anyway: bool = False) -> int:
    """The sign-off of the plant (``device`` None) or of one device by a named ``account``, as the
    record page's sign buttons do; devices without a checkout, with a failed one or with settings not
    approved are listed, and nothing is signed unless ``sign_anyway``."""
    from app.report import device_content, plant_content, recorded, sign_gaps

    if not name.strip():
        out(_("commission: a sign-off needs a name"))
        return 2
    if role != "engineer":  # the page disables the button; the record service refuses as well
        out(_("commission: {user} has the {role} role and may not add to the commissioning record").format(user=user, role=_(role) if role else _("no")))
        return 1
    if not account:
        out(_("commission: not signed: a sign-off needs a named account: give it with --account NAME (create one with "
              "'commission user add NAME --role engineer')"))
        return 1
    try:
        content = await (device_content(runtime, device, user=user, role=role) if device
                         else plant_content(runtime, user=user, role=role))
        gaps = sign_gaps(content, cli_lang.lang())
        if gaps:
            out(_("Signing anyway (--yes) although:") if sign_anyway else _("Not signed: before signing, look at these:"))
            for line in gaps:
                out(f"  {line}")
            if not sign_anyway:
                out(_("Run the missing checkouts and approve the sets, or sign anyway with --yes."))
                return 1
        entry_id = await runtime.record.sign(device or "", user=user, role=role, name=name.strip(), signer_role=signer_role,
                                             comment=comment, content=content, account=account)
    except PermissionError as exc:
        out(f"commission: {_said(exc)}")
        return 1
    except RecordError as exc:
        out(_("commission: not signed: {error}").format(error=_said(exc)))
        return 1
    entry = await runtime.record.get(entry_id)
    what = _("device {name}").format(name=device) if device else _("plant {name}").format(name=runtime.plant.name)
    out(_("{what}: signed by {name} ({role}) with account {account}, record {id}, sha256 {sha256}...").format(
        what=what, name=name.strip(), role=signer_role, account=account, id=entry_id, sha256=entry.data["sha256"][:16]))
    if not device:
        for d in content["devices"]:
            counts = d["counts"]
            checks = ", ".join(f"{recorded(c['title'], c, cli_lang.lang())}: {_(c['last'])} (" + cli_lang.lang().ngettext("{n} run", "{n} runs", c["runs"]).format(n=c["runs"]) + ")"
                               for c in d["checkout_summary"]) or _("no checkout")
            out(_("  {device}: {checks}; {changed} changed, {not_approved} not approved").format(
                device=d["device"], checks=checks, changed=counts["changed"], not_approved=counts["not approved"]))
    return 0


def run_sign(args) -> int:
    device = args.device
    args.device, args.all = ([device] if device else []), not device  # wait for the devices the content reads
    password = read_password(args.account)

    async def work(runtime, _names) -> int:
        account = await login_account(runtime, args.account, password)
        if account is None:
            return 1
        return await sign_record(runtime, user=_cli_user(), role="engineer", name=args.name, comment=args.comment,
                                 signer_role=args.signer_role, device=device, account=account, sign_anyway=args.yes)

    return _run_plant(args, work)
