"""Files and transport beyond loopback (issue 33, item 10; issue 32, item 16): the data folder is
owner-only from the first account on, HTTPS with --tls-cert/--tls-key and Secure session cookies,
and the printed address is one a browser can reach."""

from __future__ import annotations

import io
import os
import ssl
import stat
import subprocess
import time

import httpx
import pytest
from conftest import free_port
from plants import modbus_line, plant_text
from webutil import serve_beyond_loopback, stop_app

from app.cli import main, reachable_urls
from app.users import UserStore

pytestmark = pytest.mark.timeout(90)

def test_user_add_makes_the_data_folder_owner_only(tmp_path, monkeypatch):
    data = tmp_path / "new" / "data"
    monkeypatch.setattr("sys.stdin", io.StringIO("s3cret-pass\n"))
    old = os.umask(0o022)  # a usual login shell's
    try:
        assert main(["user", "add", "anna", "--role", "engineer", "--password-stdin", "--data-dir", str(data)]) == 0
    finally:
        os.umask(old)
    assert stat.S_IMODE(data.stat().st_mode) == 0o700
    assert stat.S_IMODE((data / "users.toml").stat().st_mode) == 0o600


def test_a_wildcard_address_is_printed_as_addresses_a_browser_can_reach():
    urls = reachable_urls("0.0.0.0", 8080)
    assert urls[0] == "http://127.0.0.1:8080/" and not any("0.0.0.0" in u for u in urls)
    assert reachable_urls("192.0.2.7", 8443, "https") == ["https://192.0.2.7:8443/"]
    assert reachable_urls("::1", 80) == ["http://[::1]:80/"]


def test_tls_needs_both_files(tmp_path, capsys):
    assert main_exit(["--tls-cert", str(tmp_path / "cert.pem"), "--data-dir", str(tmp_path)]) == 2
    assert "--tls-cert and --tls-key go together" in capsys.readouterr().err
    (tmp_path / "cert.pem").write_text("not a certificate")
    (tmp_path / "key.pem").write_text("not a key")
    assert main_exit(["--tls-cert", str(tmp_path / "cert.pem"), "--tls-key", str(tmp_path / "key.pem"),
                      "--data-dir", str(tmp_path)]) == 2
    assert "cannot use" in capsys.readouterr().err


def main_exit(argv: list[str]) -> int:
    try:
        return main(argv)
    except SystemExit as stop:
        return int(stop.code)


def test_https_with_secure_session_cookies(tmp_path):
    cert, key = tmp_path / "cert.pem", tmp_path / "key.pem"
    subprocess.run(["openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-days", "2", "-subj", "/CN=127.0.0.1",
                    "-addext", "subjectAltName=IP:127.0.0.1",
                    "-keyout", str(key), "-out", str(cert)], check=True, capture_output=True, timeout=60)
    data = tmp_path / "data"
    UserStore(data / "users.toml").add("anna", "engineer", "correct horse")
    (tmp_path / "plant.toml").write_text(plant_text(modbus_line(timeout=None, poll_period=None, retries=None), name=None))
    port = free_port()
    proc = serve_beyond_loopback(tmp_path, port, data, "--tls-cert", str(cert), "--tls-key", str(key))
    log = tmp_path / "app.log"
    try:
        with httpx.Client(verify=ssl.create_default_context(cafile=str(cert)), timeout=10) as client:
            answer = https_answer(client, f"https://127.0.0.1:{port}/login", proc, log)
            assert answer.status_code == 200
            cookie = answer.headers["set-cookie"].lower()
            assert "secure" in cookie and "httponly" in cookie, cookie
        with pytest.raises(httpx.TransportError):  # plain HTTP is not served on that port
            httpx.get(f"http://127.0.0.1:{port}/login", timeout=5)
        end = time.monotonic() + 10  # the start's lines reach the log file a moment after the port answers
        while f"https://127.0.0.1:{port}/" not in log.read_text() and time.monotonic() < end:
            time.sleep(0.05)
        printed = log.read_text()
        assert f"https://127.0.0.1:{port}/" in printed and "0.0.0.0" not in printed.split("at ", 1)[-1].splitlines()[0]
    finally:
        stop_app(proc)


def https_answer(client: httpx.Client, url: str, proc: subprocess.Popen, log, timeout: float = 60.0) -> httpx.Response:
    """The first answer of the server at ``url`` once it listens (polled; the app may take a while to start)."""
    end = time.monotonic() + timeout
    while True:
        try:
            return client.get(url)
        except httpx.TransportError:
            assert proc.poll() is None, log.read_text()
            assert time.monotonic() < end, f"no answer from {url} within {timeout} s"
            time.sleep(0.2)
