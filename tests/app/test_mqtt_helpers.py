"""Shared by the MQTT tests: a Mosquitto of the test's own on a free loopback port, and a subscriber."""

from __future__ import annotations

import contextlib
import socket
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path

MOSQUITTO = "/usr/sbin/mosquitto"


class Broker:
    """``mosquitto -c CONF`` on 127.0.0.1:port, written in ``folder``; start/stop/restart on the same port."""

    def __init__(self, folder: Path, port: int):
        self.folder, self.port = folder, port
        self.conf = folder / "mosquitto.conf"
        self.conf.write_text(f"listener {port} 127.0.0.1\nallow_anonymous true\npersistence false\n")
        self.proc: subprocess.Popen | None = None

    @property
    def url(self) -> str:
        return f"mqtt://127.0.0.1:{self.port}"

    def start(self, timeout: float = 10.0) -> None:
        log = open(self.folder / "mosquitto.log", "ab")  # noqa: SIM115 - the process writes it until stopped
        self.proc = subprocess.Popen([MOSQUITTO, "-c", str(self.conf)], stdout=log, stderr=subprocess.STDOUT)
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if self.proc.poll() is not None:
                raise RuntimeError(f"mosquitto exited with {self.proc.returncode}: {(self.folder / 'mosquitto.log').read_text()}")
            with contextlib.suppress(OSError), socket.create_connection(("127.0.0.1", self.port), timeout=0.2):
                return
            time.sleep(0.05)
        raise TimeoutError("mosquitto did not listen")

    def stop(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(timeout=5)
        self.proc = None


@contextlib.contextmanager
def running_broker(folder: Path, port: int) -> Iterator[Broker]:
    broker = Broker(folder, port)
    broker.start()
    try:
        yield broker
    finally:
        broker.stop()


def mqtt_table(url: str, site: str = "hall-3", **extra) -> str:
    lines = ["[mqtt]", f'url = "{url}"', f'site = "{site}"', *[f"{k} = {v!r}" for k, v in extra.items()]]
    return "\n".join(lines).replace("'", '"') + "\n"
