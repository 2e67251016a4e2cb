"""photorig.Daemon against a real photorigd on the simulated dome: submit, watch, fetch."""

import re
import socket
import subprocess
import threading

import pytest

import photorig
from conftest import BIN_DIR, SOURCE_DIR


@pytest.fixture(scope="module")
def daemon(tmp_path_factory):
    data_root = tmp_path_factory.mktemp("daemon")
    process = subprocess.Popen(
        [str(BIN_DIR / "photorigd"), "--data-root", str(data_root), "--port", "0",
         "--rig", str(SOURCE_DIR / "config/rigs/sim-dome.yaml")],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    found, ready = {}, threading.Event()

    def pump():  # the address photorigd prints, and its output drained
        for line in process.stdout:
            match = re.search(r"photorigd: open (http://127\.0\.0\.1:\d+)/", line)
            if match and "url" not in found:
                found["url"] = match.group(1)
                ready.set()
        ready.set()

    threading.Thread(target=pump, daemon=True).start()
    ready.wait(30)
    assert "url" in found, "photorigd printed no address"
    yield photorig.Daemon(found["url"]), data_root
    process.terminate()
    process.wait(30)


def test_submit_watch_fetch(daemon, tmp_path):
    client, data_root = daemon
    assert client.health()["status"] == "ok"
    run = client.submit(SOURCE_DIR / "config/recipes/ps-sphere.yaml")
    assert run["state"] == "queued" and run["plan"]["frames"] == 49
    events = list(client.watch(run["id"]))
    assert sum(1 for event, _ in events if event == "frame") == 49
    event, stop = events[-1]
    assert event == "stop" and stop["state"] == "done"
    written = client.fetch(run["id"], tmp_path, under="results")
    stored = data_root / "runs" / run["id"]
    fetched = {path.relative_to(tmp_path).as_posix() for path in written}
    assert "results/ps/normals.tiff" in fetched
    for name in fetched:
        assert (tmp_path / name).read_bytes() == (stored / name).read_bytes(), name


def test_refusals_carry_the_daemons_message(daemon):
    client, _ = daemon
    with pytest.raises(photorig.DaemonError, match="rig") as refused:
        client.submit(SOURCE_DIR / "config/recipes/tomography.yaml")
    assert refused.value.status == 422
    with pytest.raises(photorig.DaemonError) as missing:
        client.run("000999-none")
    assert missing.value.status == 404
    with pytest.raises(TypeError, match="run_id must be a str"):
        client.run(None)


def test_an_unreachable_daemon_is_named_with_its_address():
    with socket.socket() as probe:  # a port the kernel gave out, then closed: nothing listens there
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    client = photorig.Daemon(f"http://127.0.0.1:{port}", timeout_s=5)
    with pytest.raises(photorig.DaemonUnreachable, match=f"not reachable at http://127.0.0.1:{port}"):
        client.health()
    with pytest.raises(TypeError, match="url must be an address"):
        photorig.Daemon(None)
