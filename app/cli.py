"""``commission``: the GUI on a plant file, or the simulated devices of a plant alone."""

from __future__ import annotations

import argparse
import asyncio
import logging
import re
import signal
import socket
import sys
from pathlib import Path

from app import cli_lang, host, i18n
from app.cli_lang import YES, _, set_language
from app.headless import bindable, cli_user, load_plant_or_exit, refuse_taken_ports, run_headless, write_options
from app.i18n import N_
from app.message import said
from devices.errors import CommissionError

EPILOG = N_("""\
examples:
  commission                          GUI on the built-in simulated demo plant
  commission --plant site.toml        GUI on the real buses of site.toml (buses with
                                      simulate = true get their simulated devices in-process)
  commission sim --plant site.toml    only the simulated devices of site.toml, on the
                                      endpoints the file names (e.g. socket://127.0.0.1:5020),
                                      for a GUI or another Modbus master in another process
  commission --plant site.toml --no-sim
                                      GUI only, talking to devices simulated elsewhere
  commission backup --plant site.toml [--device NAME] --out DIR
                                      read every parameter into one JSON file per device
  commission restore --plant site.toml --device NAME FILE [--yes]
                                      show the diff, write, read back, save
  commission apply --plant site.toml --from FILE --devices a,b,c [--yes]
                                      one set to several devices of one type: identity
                                      check and diff per device, then device by device
  commission check --plant site.toml  the plant file and each device's project, checked
                                      by the parameter model without the devices
  commission user add NAME --role engineer|viewer
                                      accounts; needed for --host beyond 127.0.0.1
  commission view --broker mqtt://broker.local:1883
                                      read-only plant-wide view of every instance publishing
                                      to that broker (plant files with an [mqtt] table); no
                                      plant file, no buses, nothing written anywhere

The plant file (TOML) lists [[bus]] and [[device]] tables; see README.md.
""")

# argparse formats help with %: the Windows variable's signs are doubled
DATA_DIR_HELP = N_("accounts, audit database and backups (default: $COMMISSION_DATA_DIR, else the user data folder: "
                   "~/.local/share/commission on Linux, %%LOCALAPPDATA%%\\commission on Windows, "
                   "~/Library/Application Support/commission on macOS)")


class _Words:
    """argparse's own words (usage, the section titles) in the command's language."""

    def add_usage(self, usage, actions, groups, prefix=None):
        return super().add_usage(usage, actions, groups, _("usage: ") if prefix is None else prefix)

    def start_section(self, heading):
        return super().start_section(_(heading) if heading else heading)


class HelpFormatter(_Words, argparse.HelpFormatter):
    pass


class RawHelpFormatter(_Words, argparse.RawDescriptionHelpFormatter):
    """The top-level help: its examples keep their lines."""


ARGPARSE_WORDS = (N_("options"), N_("positional arguments"), N_("show this help message and exit"))


class ArgumentParser(argparse.ArgumentParser):
    """An argument parser whose built-in help option and error line speak the command's language."""

    def __init__(self, *args, **kwargs):
        kwargs.setdefault("formatter_class", HelpFormatter)
        kwargs["add_help"] = False
        super().__init__(*args, **kwargs)
        self.add_argument("-h", "--help", action="help", default=argparse.SUPPRESS, help=_("show this help message and exit"))

    def error(self, message):
        self.print_usage(sys.stderr)
        self.exit(2, _("{prog}: error: {message}").format(prog=self.prog, message=argparse_message(message)) + "\n")


# argparse's own refusals, as Python 3.10-3.13 word them: translated by their shape (others pass as they are)
ARGPARSE_ERRORS = (
    (re.compile(r"the following arguments are required: (?P<names>.+)"), N_("the following arguments are required: {names}")),
    (re.compile(r"unrecognized arguments: (?P<words>.+)"), N_("unrecognized arguments: {words}")),
    (re.compile(r"argument (?P<argument>[^:]+): invalid choice: (?P<value>.+?) \(choose from (?P<choices>.+)\)"),
     N_("argument {argument}: invalid choice: {value} (choose from {choices})")),
    (re.compile(r"argument (?P<argument>[^:]+): expected one argument"), N_("argument {argument}: expected one argument")),
    (re.compile(r"argument (?P<argument>[^:]+): invalid (?P<kind>\w+) value: (?P<value>.+)"),
     N_("argument {argument}: invalid {kind} value: {value}")),
)


def argparse_message(message: str) -> str:
    """An argparse refusal in the command's language."""
    for pattern, words in ARGPARSE_ERRORS:
        match = pattern.fullmatch(message)
        if match is not None:
            return _(words).format(**match.groupdict())
    return message


def build_parser() -> argparse.ArgumentParser:
    parser = ArgumentParser(
        prog="commission",
        description=_("Browser-based commissioning tool for field devices on CAN, Modbus RTU and serial lines."),
        epilog=_(EPILOG),
        formatter_class=RawHelpFormatter,
    )
    parser.set_defaults(func=None)  # a subcommand that brings its own runner sets it (app/dbc.py, ...)
    parser.add_argument("--lang", choices=sorted(i18n.LANGUAGES), default=None,
                        help=_("language of the messages and of this help (default: from LANG, else English)"))
    parser.add_argument("--plant", type=Path, default=None, help=_("plant file (default: the built-in demo plant)"))
    parser.add_argument("--host", default="127.0.0.1", help=_("address to serve the GUI on (default: 127.0.0.1, loopback only)"))
    parser.add_argument("--port", type=int, default=8080, help=_("HTTP port of the GUI (default: 8080)"))
    parser.add_argument("--allowed-host", action="append", default=[], metavar="NAME",
                        help=_("a further host name or address browsers use to reach the GUI (repeatable); "
                             "requests for any other name are refused (DNS rebinding)"))
    parser.add_argument("--tls-cert", type=Path, default=None, metavar="FILE",
                        help=_("serve HTTPS with this certificate (PEM, the chain after it); session cookies are then Secure"))
    parser.add_argument("--tls-key", type=Path, default=None, metavar="FILE", help=_("the certificate's private key (PEM)"))
    parser.add_argument("--no-sim", action="store_true", help=_("do not start simulated devices, even for buses with simulate = true"))
    parser.add_argument("--show", action="store_true", help=_("open a browser window"))
    parser.add_argument("-v", "--verbose", action="store_true", help=_("log more"))
    parser.add_argument("--data-dir", type=Path, default=None,
                        help=_(DATA_DIR_HELP))
    sub = parser.add_subparsers(dest="command", parser_class=ArgumentParser)
    sim = sub.add_parser("sim", help=_("run only the simulated devices of a plant file"))
    sim.add_argument("--plant", type=Path, default=None, help=_("plant file (default: the built-in demo plant)"))
    sim.add_argument("--all", action="store_true", help=_("simulate every bus, not only those with simulate = true"))

    backup = sub.add_parser("backup", help=_("back up the parameters of one device or the whole plant, headless"))
    backup.add_argument("--plant", type=Path, default=None, help=_("plant file (default: the built-in demo plant)"))
    backup.add_argument("--device", action="append", default=[], help=_("device name (repeatable; default: every device)"))
    backup.add_argument("--out", type=Path, required=True, help=_("folder for the backup files"))
    backup.add_argument("--no-sim", action="store_true", help=_("do not start simulated devices"))

    restore = sub.add_parser("restore", help=_("restore one device from a backup file, headless"))
    restore.add_argument("--plant", type=Path, default=None, help=_("plant file (default: the built-in demo plant)"))
    restore.add_argument("--device", required=True, help=_("device name"))
    restore.add_argument("file", type=Path, help=_("backup file (JSON)"))
    write_options(restore)
    restore.add_argument("--no-sim", action="store_true", help=_("do not start simulated devices"))

    user = sub.add_parser("user", help=_("manage accounts (needed to serve beyond the loopback address)"))
    user_sub = user.add_subparsers(dest="user_command", required=True)
    add = user_sub.add_parser("add", help=_("add or replace an account"))
    add.add_argument("name")
    add.add_argument("--role", choices=["engineer", "viewer"], required=True)
    add.add_argument("--password-stdin", action="store_true", help=_("read the password from standard input"))
    remove = user_sub.add_parser("remove", help=_("remove an account"))
    remove.add_argument("name")
    listing = user_sub.add_parser("list", help=_("list accounts"))

    from app import dbc

    dbc.add_parser(sub)

    from app import report_archive

    report_archive.add_parser(sub)  # commission report --plant P --out DIR: the as-left report without a browser

    from app import record_cli

    record_cli.add_parsers(sub)  # commission approve / checkout / sign: the commissioning record without a browser

    from app import batch, project

    batch.add_parser(sub)  # commission apply --plant P --from FILE --devices a,b,c: one set to several devices
    project.add_parser(sub)  # commission check --plant P: the plant file and its devices' projects, without the devices

    from app import mcap_export

    mcap_export.add_parser(sub)  # commission export --format mcap: a recording or the live data for Foxglove, PlotJuggler

    view = sub.add_parser("view", help=_("read-only plant-wide view of every site publishing to an MQTT broker"))
    view.add_argument("--broker", required=True, metavar="URL", help=_("mqtt://host[:1883] or mqtts://host[:8883]"))
    view.add_argument("--username", default=None, help=_("broker user name"))
    view.add_argument("--password-env", default=None, metavar="VAR", help=_("environment variable holding the broker password"))
    view.add_argument("--password-file", type=Path, default=None, metavar="FILE", help=_("file holding the broker password"))
    view.add_argument("--ca-file", type=Path, default=None, help=_("mqtts: CA certificate(s) of the broker"))
    view.add_argument("--host", default="127.0.0.1", help=_("address to serve the view on (default: 127.0.0.1)"))
    view.add_argument("--port", type=int, default=8090, help=_("HTTP port of the view (default: 8090)"))
    view.add_argument("--allowed-host", action="append", default=[], metavar="NAME",
                      help=_("a further host name browsers use to reach the view (repeatable)"))
    view.add_argument("--public", action="store_true",
                      help=_("allow --host beyond the loopback address: the view has no login and shows every published value"))

    for command in (sim, backup, restore, user, add, remove, listing):
        # SUPPRESS: a subcommand's default must not overwrite a --data-dir given before it
        command.add_argument("--data-dir", type=Path, default=argparse.SUPPRESS,
                             help=_(DATA_DIR_HELP))
    return parser


def reachable_urls(host: str, port: int, scheme: str = "http") -> list[str]:
    """The addresses a browser can use for a server listening on ``host``: for a wildcard address
    (0.0.0.0, ::) this machine's name and its outward IP addresses, loopback first; else the address."""
    if host not in ("0.0.0.0", "::", ""):
        name = f"[{host}]" if ":" in host else host
        return [f"{scheme}://{name}:{port}/"]
    names = ["127.0.0.1"]
    machine = socket.gethostname()
    if machine and machine != "localhost":
        names.append(machine)
    addresses: list[str] = []
    try:  # the address of the interface a packet outward would leave by (nothing is sent)
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
            probe.connect(("192.0.2.1", 9))
            addresses.append(probe.getsockname()[0])
    except OSError:
        pass
    try:
        addresses += [info[4][0] for info in socket.getaddrinfo(machine, None, socket.AF_INET)]
    except OSError:
        pass
    for address in addresses:
        if not address.startswith("127.") and address not in names:
            names.append(address)
    return [f"{scheme}://{name}:{port}/" for name in names]


def _tls_files(args) -> tuple[str, str] | None:
    """``(cert, key)`` for HTTPS, None for HTTP; SystemExit(2) with the reason when they cannot be used."""
    if not args.tls_cert and not args.tls_key:
        return None
    if not (args.tls_cert and args.tls_key):
        print(_("commission: --tls-cert and --tls-key go together (the certificate and its private key)"), file=sys.stderr)
        raise SystemExit(2)
    import ssl

    context = ssl.SSLContext(ssl.PROTOCOL_TLS_SERVER)
    try:
        context.load_cert_chain(args.tls_cert, args.tls_key)
    except (OSError, ssl.SSLError) as exc:
        print(_("commission: cannot use {cert} with {key}: {error}").format(
            cert=args.tls_cert, key=args.tls_key, error=exc.strerror or exc), file=sys.stderr)
        raise SystemExit(2) from None
    return str(args.tls_cert), str(args.tls_key)


def _quiet_libraries(verbose: bool) -> None:
    logging.basicConfig(level=logging.DEBUG if verbose else logging.INFO, format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    logging.getLogger("pymodbus").setLevel(logging.DEBUG if verbose else logging.CRITICAL)
    logging.getLogger("can").setLevel(logging.INFO if verbose else logging.WARNING)


def run_sim(args) -> int:
    from app.runtime import SimulatedPlant

    plant = load_plant_or_exit(args.plant)
    sim = SimulatedPlant(plant, only_flagged=not args.all)
    if not sim.servers:
        print(_("commission sim: the plant file has no bus with simulate = true (use --all to simulate every bus)"), file=sys.stderr)
        return 2
    if refuse_taken_ports(plant, "commission sim", every=args.all):
        return 2

    async def main() -> None:
        errors = await sim.start()
        if errors:
            for error in errors:
                print(f"commission sim: {error}", file=sys.stderr)
            await sim.stop()
            raise SystemExit(1)
        for bus in plant.buses.values():
            if bus.simulated or args.all:
                devices = plant.devices_on(bus.name) + [d for d in plant.sim_devices.values() if d.bus == bus.name]
                names = ", ".join(d.name for d in devices)
                print(_("simulating {bus} ({type}) on {endpoint}: {names}").format(
                    bus=bus.name, type=bus.type, endpoint=bus.endpoint, names=names), flush=True)
                if bus.options.get("interface") == "virtual":
                    print(
                        _("  note: {bus} uses the virtual CAN interface, which other processes cannot reach; "
                          'use interface = "udp_multicast" (channel "239.74.163.2") to share it across processes').format(bus=bus.name),
                        file=sys.stderr, flush=True,
                    )
        from app.runtime import freeze_startup_heap

        freeze_startup_heap()  # the twins' threads and timers then wait less for the collector
        stop = asyncio.Event()
        # the loop's own signal handlers on Unix; Windows' loops have none: the interpreter's (app/host.py)
        undo = host.on_stop_signals(asyncio.get_running_loop(), stop.set)
        try:
            await stop.wait()
            await sim.stop()  # a second Ctrl+C meanwhile changes nothing
        finally:
            undo()

    asyncio.run(main())
    return 0


def run_user(args) -> int:
    import getpass

    from app.users import UserError, UserStore, default_data_dir

    try:
        store = UserStore((args.data_dir or default_data_dir()) / "users.toml")
    except UserError as exc:
        print(f"commission user: {exc}", file=sys.stderr)
        return 2
    if args.user_command == "list":
        for user in sorted(store.users.values(), key=lambda u: u.name):
            print(f"{user.name}\t{user.role}")
        return 0
    if args.user_command == "remove":
        if not store.remove(args.name):
            print(_("commission user: no account named {name}").format(name=args.name), file=sys.stderr)
            return 2
        print(_("removed {name}").format(name=args.name))
        return 0
    if args.password_stdin or not sys.stdin.isatty():
        password = sys.stdin.readline().rstrip("\n")
    else:
        password = getpass.getpass(_("password for {name}: ").format(name=args.name))
        if getpass.getpass(_("again: ")) != password:
            print(_("commission user: the passwords differ"), file=sys.stderr)
            return 2
    try:
        store.add(args.name, args.role, password)
    except UserError as exc:
        print(f"commission user: {exc}", file=sys.stderr)
        return 2
    print(_("{name} ({role}) saved in {path}").format(name=args.name, role=args.role, path=store.path))
    return 0


def run_backup(args) -> int:
    from app import backup

    async def work(runtime, names) -> int:
        failures = 0
        for name in names:
            state = runtime.store.devices[name]
            reason = await backup.nothing_to_back_up(runtime.worker.adapters[name])
            if reason:
                print(_("{name}: skipped: {reason}").format(name=name, reason=said(reason, cli_lang.lang())), flush=True)
                continue
            if state.status != "online":
                print(_("{name}: not answering ({error}): skipped").format(
                    name=name, error=said(state.last_error, cli_lang.lang()) if state.last_error else _("no answer")),
                      file=sys.stderr)
                failures += 1
                continue
            try:
                path = await backup.backup_device(runtime, name, args.out, user=cli_user(), role="engineer")
            except (CommissionError, OSError) as exc:  # one device's refusal or a file not written: the others go on
                print(_("{name}: backup failed: {error}").format(name=name, error=said(exc, cli_lang.lang())), file=sys.stderr)
                failures += 1
                continue
            print(f"{name}: {path}")
        return 1 if failures else 0

    return asyncio.run(run_headless(args, work, answers_needed=backup.device_backs_up))


def run_restore(args) -> int:
    from app import backup

    try:
        from app import files

        document = backup.load_document(files.read_regular(args.file, files.MAX_DOCUMENT_BYTES, "backup file"), str(args.file))
    except (OSError, backup.BackupError) as exc:
        print(f"commission restore: {said(exc, cli_lang.lang())}", file=sys.stderr)
        return 2

    async def work(runtime, names) -> int:
        name = names[0]
        if runtime.store.devices[name].status != "online":
            print(_("{name}: not answering: {error}").format(name=name, error=said(runtime.store.devices[name].last_error or "",
                                                                                   cli_lang.lang())), file=sys.stderr)
            return 1
        try:
            plan = await backup.plan_restore(runtime, name, document)
        except CommissionError as exc:
            print(f"commission restore: {said(exc, cli_lang.lang())}", file=sys.stderr)
            return 2
        for warning in plan.warnings:
            print(_("warning: {warning}").format(warning=said(warning, cli_lang.lang())))
        changed = [r for r in plan.rows if r.changed]
        for row in changed:
            mark = _("   [needs confirmation: {risk}]").format(risk=row.risk) if row.risk else ""
            print(f"  {row.name}: {row.current_text} -> {row.backup_text}{mark}")
        if not changed:
            print(_("nothing to write: the device already holds the backed-up values")
                  + (_(" (invalid entries of the file are listed above)") if plan.invalid else ""))
            return 1 if plan.invalid else 0
        selected = {r.key for r in changed}
        wear = backup.restore_wear(runtime, name)
        if wear:
            print(_("note: {wear}: this restore makes {count} such write(s)").format(wear=wear, count=len(changed)))
        risky = plan.risky(selected)
        accepted = {n.lower() for n in args.accept_risk}
        confirmed = {r.key for r in risky if r.name.lower() in accepted}
        if not args.yes:
            if not sys.stdin.isatty():
                print(_("commission restore: add --yes to write without a terminal to confirm"), file=sys.stderr)
                return 2
            if input(_("write {count} parameters to {name}? [y/N] ").format(count=len(changed), name=name)).strip().lower() \
                    not in YES:
                print(_("nothing written"))
                return 1
            for row in risky:
                if row.key not in confirmed and input(_("{name} = {value}: {risk} Write it? [y/N] ").format(
                        name=row.name, value=row.backup_text, risk=row.risk)).strip().lower() in YES:
                    confirmed.add(row.key)
        unconfirmed = [r for r in risky if r.key not in confirmed]
        if unconfirmed:
            for row in unconfirmed:
                print(_("commission restore: {name} = {value} needs a confirmation ({risk}); "
                        "name it with --accept-risk {name} to write it").format(name=row.name, value=row.backup_text, risk=row.risk),
                      file=sys.stderr)
            print(_("nothing written"), file=sys.stderr)
            return 2
        report = await backup.execute_restore(runtime, plan, selected, user=cli_user(), confirmed=confirmed)
        for parameter, error in report.failed + report.refused:
            print(_("  failed: {parameter}: {error}").format(parameter=parameter, error=said(error, cli_lang.lang())), file=sys.stderr)
        print(said(report.summary(), cli_lang.lang()))
        return 0 if report.ok else 1

    return asyncio.run(run_headless(args, work))


def run_view(args) -> int:
    """``commission view``: subscribe to the broker and serve the read-only plant-wide view."""
    import os

    from app.plant import parse_mqtt_url
    from app.site_view import SiteStore
    from app.users import is_loopback

    try:
        parse_mqtt_url(args.broker)
    except ValueError as exc:
        print(f"commission view: --broker {said(exc, cli_lang.lang())}", file=sys.stderr)
        return 2
    if args.ca_file and not args.broker.startswith("mqtts://"):
        print(_("commission view: --ca-file is for TLS: give the broker as mqtts://..."), file=sys.stderr)
        return 2
    password = None
    if args.password_env:
        password = os.environ.get(args.password_env)
        if password is None:
            print(_("commission view: the environment variable {name} is not set").format(name=args.password_env), file=sys.stderr)
            return 2
    elif args.password_file:
        try:
            from app import files

            password = files.read_regular_text(args.password_file, files.MAX_SECRET_BYTES, "password file").strip()
        except (OSError, ValueError) as exc:
            print(_("commission view: cannot read {file}: {error}").format(file=args.password_file, error=exc.strerror or exc),
                  file=sys.stderr)
            return 2
    if not is_loopback(args.host) and not args.public:
        print(_("commission view: refusing to listen on {host}: the view has no login and shows every value published "
                "to the broker; add --public if everyone who can reach this address may see them").format(host=args.host),
              file=sys.stderr)
        return 2
    if not bindable(args.host, args.port):
        print(_("commission view: port {port} on {host} is taken; choose another with --port").format(port=args.port, host=args.host),
              file=sys.stderr)
        return 2
    store = SiteStore(args.broker, args.username, password, str(args.ca_file) if args.ca_file else None)
    import tempfile

    # the view keeps nothing per browser; NiceGUI's storage folder goes to a temporary place, not the working folder
    os.environ.setdefault("NICEGUI_STORAGE_PATH", tempfile.mkdtemp(prefix="commission-view-"))

    from nicegui import ui

    import server
    from app import web

    server.register_view(store, host=args.host, allowed_hosts=args.allowed_host)
    print(_("commission view: {broker} at {url} (read-only)").format(broker=args.broker, url=f"http://{args.host}:{args.port}/"),
          flush=True)
    ui.run(host=args.host, port=args.port, title="commission view", reload=False, show=False,
           show_welcome_message=False, favicon="🔧", tailwind=False,  # rules compiled beforehand: app/assets.py
           reconnect_timeout=web.RECONNECT_S)
    return 0




def main(argv: list[str] | None = None) -> int:
    try:
        return _main(argv)
    except KeyboardInterrupt:
        print(_("commission: stopped (Ctrl-C)"), file=sys.stderr, flush=True)
        return 130


def _main(argv: list[str] | None) -> int:
    set_language(i18n.cli_language(argv))  # before the parser: its help is in that language
    args = build_parser().parse_args(argv)
    _quiet_libraries(args.verbose)
    commands = {"sim": run_sim, "backup": run_backup, "restore": run_restore, "user": run_user, "view": run_view}
    if args.command in commands:
        return commands[args.command](args)
    if args.func is not None:  # subcommands that bring their own runner (dbc)
        return args.func(args)

    from app.users import UserStore, default_data_dir, is_loopback

    data_dir = args.data_dir or default_data_dir()
    auth_required = not is_loopback(args.host)
    tls = _tls_files(args)
    if auth_required and not UserStore(data_dir / "users.toml").has_engineer():
        print(
            _("commission: refusing to listen on {host}: beyond the loopback address every browser must log in, "
              "and there is no engineer account yet. Add one with\n"
              "  {command}\n"
              "or serve on 127.0.0.1 only (the default).").format(
                host=args.host,
                command=f"commission user add NAME --role engineer{'' if args.data_dir is None else f' --data-dir {args.data_dir}'}"),
            file=sys.stderr,
        )
        return 2

    import os

    from app.runtime import secure_data_dir

    host.private_umask()  # sessions, accounts, audit, backups and recordings: owner only (Windows: the profile's ACL)
    secure_data_dir(data_dir)
    # NiceGUI keeps its per-browser storage here instead of the working folder
    os.environ.setdefault("NICEGUI_STORAGE_PATH", str(data_dir / "nicegui"))

    from nicegui import ui

    import server  # the composition root: the pages' routes on app/web.py's server
    from app import web
    from app.runtime import Runtime

    plant = load_plant_or_exit(args.plant)
    if not bindable(args.host, args.port):
        print(_("commission: port {port} on {host} is taken (another commission or another program); "
                "choose another with --port").format(port=args.port, host=args.host), file=sys.stderr)
        return 2
    if not args.no_sim and refuse_taken_ports(plant):
        return 2
    from app.runtime import raise_priority

    raise_priority()  # before any thread starts: they all inherit it (the keep-alive threads ask for more)
    runtime = Runtime(plant, simulate=not args.no_sim, data_dir=data_dir, auth_required=auth_required)
    server.register(runtime, host=args.host, allowed_hosts=args.allowed_host)
    url = _(" and ").join(reachable_urls(args.host, args.port, "https" if tls else "http"))
    if auth_required and tls is None:
        print(_("commission: note: served beyond the loopback address without --tls-cert/--tls-key, passwords and session "
                "cookies cross the network unencrypted"), file=sys.stderr, flush=True)
    announce_task: list[asyncio.Task] = []
    kept: list[object] = []

    async def announce() -> None:
        """Print the URL once the server accepts connections (uvicorn binds after the startup handlers)."""
        probe = "127.0.0.1" if args.host in ("0.0.0.0", "") else "::1" if args.host == "::" else args.host
        loop = asyncio.get_running_loop()
        end = loop.time() + 30
        while loop.time() < end:
            try:
                _reader, writer = await asyncio.open_connection(probe, args.port)
            except OSError:
                await asyncio.sleep(0.1)
                continue
            writer.close()
            from app.runtime import FullCollections, freeze_startup_heap

            frozen = freeze_startup_heap()  # started: what is there now stays, the collector need not walk it
            logging.getLogger("app.cli").debug("%d objects of the start frozen", frozen)
            collections = FullCollections()  # and the full collections wait while a motion runs under a lease
            collections.start()
            kept.append(collections)  # referenced while the server runs
            print(_("commission: plant '{plant}' ({count} devices) at {url}").format(plant=plant.name, count=len(plant.devices), url=url),
                  flush=True)
            return
        print(_("commission: the GUI did not start listening on {host}:{port}").format(host=args.host, port=args.port),
              file=sys.stderr, flush=True)

    from nicegui import app as gui_app

    gui_app.on_startup(lambda: announce_task.append(asyncio.create_task(announce(), name="announce")))
    interrupted: list[int] = []

    def on_interrupt(signum, frame) -> None:
        """While it serves, uvicorn takes Ctrl-C itself, stops the server and then raises the signal again:
        once serving has begun (``announce_task``) it is only noted, since a KeyboardInterrupt then cuts the
        server's clean-up short with a traceback."""
        if not announce_task:
            raise KeyboardInterrupt
        interrupted.append(signum)

    host.set_interrupt_handler(on_interrupt)
    ui.run(
        host=args.host,
        port=args.port,
        title="commission",
        show=args.show,
        reload=False,
        show_welcome_message=False,
        favicon="🔧",
        storage_secret=web.storage_secret(data_dir),
        # over HTTPS the session cookie is Secure: a browser never sends it over plain HTTP
        session_middleware_kwargs={"https_only": True} if tls else None,
        **({"ssl_certfile": tls[0], "ssl_keyfile": tls[1]} if tls else {}),
        # pages get many small updates: compressing each one cost the event loop more than all the rest of
        # sending it (with 20 pages open, a third of the loop's time); the messages are small JSON
        ws_per_message_deflate=False,
        tailwind=False,  # the pages' Tailwind rules are compiled beforehand, not in every browser (app/assets.py)
        reconnect_timeout=web.RECONNECT_S,  # a page survives a busy browser and a short network outage
    )
    if signal.SIGINT in interrupted:
        raise KeyboardInterrupt  # the one-line message of main()
    return 0


if __name__ == "__main__":
    sys.exit(main())
