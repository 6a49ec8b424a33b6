"""The real HAProxy (Debian's) in front of two `saddlescope serve` replicas on object storage (issue 26 part 4).

The proxy runs the committed `deploy/haproxy.cfg`, changed only where a test must: it listens on a free
127.0.0.1 port with TLS (a throw-away certificate made by openssl, so its own `ssl_fc` rule says https),
its two servers are the replicas' ports instead of Docker's DNS, and it connects from 127.0.0.2, the one
address the replicas trust for forwarded headers. The replicas share a SQLite file and a bucket on the
session's SeaweedFS (tests/s3_server.py) and no folder for clips. Checked: requests reach both replicas;
a resumable (streamed) upload started on one continues on the other and, with one replica killed
mid-upload, completes on the survivor; cookies carry Secure behind the proxy and not when a client
sends X-Forwarded-Proto itself.
"""

from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import httpx
import pytest
import s3_server as s3_server_module
from integration_services import service_env, stop_process, write_tiny_clip

s3_server = s3_server_module.s3_server  # one SeaweedFS for the session (tests/s3_server.py)

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[2]
IN_CI = os.environ.get("CI", "").lower() in {"1", "true", "yes"}
PROXY_SOURCE = "127.0.0.2"  # the proxy's address as the replicas see it: the only one they trust
EMAIL, PASSWORD = "secretary@replicas.example", "correct horse 1"


def _require(tool: str) -> str:
    found = shutil.which(tool)
    if found is None:
        message = f"{tool} is not installed (apt-get install {tool})"
        if IN_CI:
            pytest.fail(f"{message}; CI=true requires the proxy test to run")
        pytest.skip(message)
    return found


def _free_port() -> int:
    import socket

    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def _wait(url: str, proc: subprocess.Popen, log: Path, *, timeout_s: float = 120.0, **kwargs) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            pytest.fail(f"{proc.args[0]} exited with {proc.returncode}:\n{log.read_text()[-3000:]}")
        try:
            if httpx.get(url, timeout=5, **kwargs).status_code == 200:
                return
        except httpx.TransportError:
            pass
        time.sleep(0.3)
    pytest.fail(f"{url} did not answer within {timeout_s} s:\n{log.read_text()[-3000:]}")


def proxy_config(ports: list[int], listen_port: int, pem: Path) -> str:
    """deploy/haproxy.cfg with the test's listening port, TLS certificate and two fixed servers."""
    text = (ROOT / "deploy" / "haproxy.cfg").read_text()
    text = re.sub(r"\nresolvers docker\n(?:    .*\n)+", "\n", text)
    text = text.replace("    bind :8000\n", f"    bind 127.0.0.1:{listen_port} ssl crt {pem}\n")
    servers = "".join(f"    server api-{i} 127.0.0.1:{port}\n" for i, port in enumerate(ports, 1))
    text = re.sub(r"    server-template .*\n", servers, text)
    assert text.count("    server api-") == len(ports), "deploy/haproxy.cfg changed shape: update this test"
    text = text.replace("    default-server inter 5s fall 3 rise 2 check\n",
                        f"    default-server inter 1s fall 2 rise 1 check\n    source {PROXY_SOURCE}\n"
                        "    http-response set-header X-Served-By %s\n")
    text = text.replace("    log stdout format raw local0 info\n", "")
    return text


@pytest.fixture(scope="module")
def deployed(tmp_path_factory, s3_server):
    haproxy, openssl = _require("haproxy"), _require("openssl")
    root = tmp_path_factory.mktemp("replicas")
    pem = root / "proxy.pem"
    subprocess.run([openssl, "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-days", "1", "-subj",
                    "/CN=localhost", "-keyout", str(pem), "-out", str(pem)], check=True, capture_output=True)
    bucket = s3_server.new_bucket("replicas")
    env = service_env(database_url=f"sqlite:///{root / 'db.sqlite'}", storage_dir=root / "no-clips-here")
    env.update(s3_server.environ(), SADDLESCOPE_STORAGE_URL=f"s3://{bucket}/club",
               SADDLESCOPE_DIRECT_UPLOADS="false",  # chunks through the replicas: the harder case
               SADDLESCOPE_FORWARDED_ALLOW_IPS=PROXY_SOURCE,
               PYTHONPATH=os.pathsep.join(p for p in sys.path if p))
    replicas: dict[str, subprocess.Popen] = {}
    ports = [_free_port(), _free_port()]
    procs: list[subprocess.Popen] = []
    try:
        for i, port in enumerate(ports, 1):  # one after the other: the first makes the database
            log = root / f"api-{i}.log"
            with log.open("wb") as out:
                proc = subprocess.Popen([sys.executable, "-m", "saddlescope.cli", "serve", "--host", "127.0.0.1",
                                         "--port", str(port)], cwd=root, env=env, stdout=out,
                                        stderr=subprocess.STDOUT)
            procs.append(proc)
            replicas[f"api-{i}"] = proc
            _wait(f"http://127.0.0.1:{port}/api/health", proc, log)
        listen = _free_port()
        cfg = root / "haproxy.cfg"
        cfg.write_text(proxy_config(ports, listen, pem))
        log = root / "haproxy.log"
        with log.open("wb") as out:
            proxy = subprocess.Popen([haproxy, "-db", "-f", str(cfg)], stdout=out, stderr=subprocess.STDOUT)
        procs.append(proxy)
        base = f"https://127.0.0.1:{listen}"
        _wait(f"{base}/api/health", proxy, log, verify=False)
        yield {"base": base, "replicas": replicas, "ports": ports, "root": root, "bucket": bucket}
    finally:
        for proc in reversed(procs):
            stop_process(proc)


def _client(deployed) -> httpx.Client:
    return httpx.Client(base_url=deployed["base"], verify=False, timeout=60)


def _signed_in(deployed) -> httpx.Client:
    client = _client(deployed)
    created = client.post("/api/clubs", json={"club_name": "Replica Club", "email": EMAIL, "password": PASSWORD})
    assert created.status_code in (201, 409), created.text
    login = client.post("/api/auth/login", json={"email": EMAIL, "password": PASSWORD})
    assert login.status_code == 200, login.text
    client.cookies.clear()
    client.headers["Authorization"] = f"Bearer {login.json()['access_token']}"
    return client


def test_requests_reach_both_replicas(deployed):
    with _client(deployed) as client:
        served_by = {client.get("/api/health").headers["X-Served-By"] for _ in range(8)}
    assert served_by == {"api-1", "api-2"}


SECURITY_HEADERS = ("content-security-policy", "x-frame-options", "x-content-type-options", "referrer-policy",
                    "permissions-policy")


def test_every_answer_carries_the_browser_security_headers(deployed):
    with _client(deployed) as client:
        own, api = client.get("/proxy-health"), client.get("/api/health")  # the proxy's own; the API's
    for answer in (own, api):
        assert answer.status_code == 200
        assert not [h for h in SECURITY_HEADERS if h not in answer.headers], answer.headers
        assert answer.headers["x-frame-options"] == "DENY"
        assert "frame-ancestors 'none'" in answer.headers["content-security-policy"]
    assert own.headers["content-security-policy"] == "default-src 'none'; frame-ancestors 'none'"
    assert "script-src 'self'" in api.headers["content-security-policy"]  # the API's own policy kept
    assert len(api.headers.get_list("content-security-policy")) == 1


def test_cookies_are_secure_behind_the_proxy_and_forwarded_headers_from_others_are_ignored(deployed):
    _signed_in(deployed).close()  # the club exists
    with _client(deployed) as client:
        login = client.post("/api/auth/login", json={"email": EMAIL, "password": PASSWORD})
    cookies = login.headers.get_list("set-cookie")
    assert cookies and all("secure" in c.lower() for c in cookies), cookies
    direct = f"http://127.0.0.1:{deployed['ports'][0]}"  # a client on 127.0.0.1 claiming https
    spoofed = httpx.post(f"{direct}/api/auth/login", json={"email": EMAIL, "password": PASSWORD},
                         headers={"X-Forwarded-Proto": "https"}, timeout=30)
    assert spoofed.status_code == 200
    cookies = spoofed.headers.get_list("set-cookie")
    assert cookies and not any("secure" in c.lower() for c in cookies), cookies


def test_an_upload_continues_on_the_other_replica_and_survives_one_being_killed(deployed):
    client = _signed_in(deployed)
    horse = client.post("/api/horses", json={"name": "Replica"}).json()
    rider = client.post("/api/riders", json={"name": "Replica"}).json()
    ride = client.post("/api/rides", json={"horse_id": horse["id"], "rider_id": rider["id"], "gait": "walk",
                                          "direction": "CW"}).json()
    data = write_tiny_clip(deployed["root"] / "left.avi", frames=21, size=(640, 480)).read_bytes()
    started = client.post("/api/uploads", json={"target": "ride_clip", "ride_id": ride["id"], "clip_kind": "motion",
                                                "camera": "left", "length_bytes": len(data),
                                                "filename": "left.avi"})
    assert started.status_code == 201, started.text
    upload_id = started.json()["id"]
    chunk = -(-len(data) // 6)
    offset, served_by, killed = 0, [], None
    while offset < len(data):
        sent = client.patch(f"/api/uploads/{upload_id}", content=data[offset:offset + chunk],
                            headers={"Upload-Offset": str(offset),
                                     "Content-Type": "application/offset+octet-stream"})
        assert sent.status_code == 204, sent.text
        offset = int(sent.headers["Upload-Offset"])
        served_by.append(sent.headers["X-Served-By"])
        if killed is None and len(set(served_by)) == 2:
            killed = served_by[-1]  # both replicas took chunks: kill the last one mid-upload
            proc = deployed["replicas"][killed]
            proc.send_signal(signal.SIGKILL)
            proc.wait(timeout=10)
    assert killed is not None and len(set(served_by)) == 2, served_by
    after = served_by[served_by.index(killed) + 1:]
    assert after and killed not in after, served_by  # the survivor took the rest
    head = client.head(f"/api/uploads/{upload_id}")
    assert head.status_code == 200 and head.headers["Upload-Offset"] == str(len(data))
    done = client.post(f"/api/uploads/{upload_id}/finalize")
    assert done.status_code in (200, 201), done.text
    clips = client.get(f"/api/rides/{ride['id']}/clips").json()
    assert any(c["id"] == done.json()["recording_id"] for c in clips)
    print(f"\nchunks served by {served_by}; {killed} killed mid-upload; {len(data)} bytes finalised")
    on_disk = [p for p in deployed["root"].rglob("*") if p.is_file() and p.suffix not in (".log", ".pem", ".cfg")
               and not p.name.startswith(("db.sqlite", "secret_key", "left.avi"))]
    assert on_disk == [], on_disk  # no replica kept a byte of the clip on its disk
    client.close()
