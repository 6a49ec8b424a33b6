"""`saddlescope serve` and `saddlescope demo` on a taken port: one plain sentence and a non-zero exit, at once."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import time

import pytest

from saddlescope.cli import main
from saddlescope.server import PortInUse, check_port_free


@pytest.fixture
def taken_port():
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as holder:
        holder.bind(("127.0.0.1", 0))
        holder.listen(1)
        yield holder.getsockname()[1]


def test_a_taken_port_is_said_in_one_sentence_with_another_to_pick(taken_port):
    with pytest.raises(PortInUse) as caught:
        check_port_free("127.0.0.1", taken_port)
    text = str(caught.value)
    assert text == (f"port {taken_port} on 127.0.0.1 is already in use (is SaddleScope already running?): stop the "
                    f"program using it, or pick another port, e.g. saddlescope serve --port {taken_port + 1}")


def test_a_free_port_passes():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    check_port_free("127.0.0.1", port)  # closed again: free


@pytest.mark.parametrize("command", ["serve", "demo"])
def test_the_command_exits_non_zero_with_the_sentence_and_no_traceback(taken_port, command, capsys):
    started = time.monotonic()
    status = main([command, "--host", "127.0.0.1", "--port", str(taken_port)])
    err = capsys.readouterr().err
    assert status == 2
    assert err.count("\n") == 1 and f"port {taken_port} on 127.0.0.1 is already in use" in err, err
    assert ("make demo PORT=" in err) if command == "demo" else (f"saddlescope serve --port {taken_port + 1}" in err)
    assert "Traceback" not in err and "Errno" not in err
    assert time.monotonic() - started < 30  # the demo does not analyse its ride first


def test_the_installed_command_says_it_too(taken_port):
    exe = os.path.join(os.path.dirname(sys.executable), "saddlescope")
    if not os.path.exists(exe):
        pytest.skip(f"the saddlescope command is not installed beside {sys.executable}")
    done = subprocess.run([exe, "serve", "--port", str(taken_port)], capture_output=True, text=True, timeout=120)
    assert done.returncode == 2
    assert done.stderr.strip().startswith(f"saddlescope serve: port {taken_port} on 127.0.0.1 is already in use")
    assert "Traceback" not in done.stderr and done.stdout == ""
