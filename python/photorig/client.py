"""A client of photorigd's HTTP API (docs/api.md): submit a recipe, watch its
run's events, fetch its files. The standard library only: it needs no part of the
build but a daemon to talk to.

    daemon = photorig.Daemon("http://127.0.0.1:8750")
    run = daemon.submit("config/recipes/ps-sphere.yaml")
    for event, data in daemon.watch(run["id"]):
        print(event, data)
    daemon.fetch(run["id"], "sphere/", under="results")
"""

import json
import os
import urllib.error
import urllib.parse
import urllib.request
import zlib
from pathlib import Path

# A run in one of these states changes no more (daemon/capture/run_control.h IsFinal).
FINAL_STATES = ("done", "failed", "aborted", "interrupted")


class DaemonError(RuntimeError):
    """An answer other than 2xx: `status` and the daemon's own message."""

    def __init__(self, status, message):
        super().__init__(f"{status}: {message}")
        self.status = status
        self.message = message


def _run_id(run_id):
    """A run's id, quoted for a path; anything but a str is a mistake."""
    if not isinstance(run_id, str):
        raise TypeError(f"run_id must be a str such as '000001-ps-sphere', not {type(run_id).__name__}")
    return urllib.parse.quote(run_id)


class DaemonUnreachable(ConnectionError):
    """Nothing answered at the daemon's address."""


class Daemon:
    def __init__(self, url="http://127.0.0.1:8750", token=None, timeout_s=30.0):
        if not isinstance(url, str) or not url.startswith(("http://", "https://")):
            raise TypeError(f"url must be an address like http://HOST:PORT, not {url!r}")
        self.url = url.rstrip("/")
        self.base = self.url + "/api/v1"
        self.token = token
        self.timeout_s = timeout_s

    def _open(self, path, body=None, headers=None, timeout_s=None):
        request = urllib.request.Request(self.base + path, data=body, headers=dict(headers or {}))
        if self.token:
            request.add_header("Authorization", f"Bearer {self.token}")
        try:
            return urllib.request.urlopen(request, timeout=timeout_s or self.timeout_s)
        except urllib.error.HTTPError as e:
            text = e.read().decode("utf-8", "replace")
            try:
                message = json.loads(text)["error"]
            except (ValueError, KeyError, TypeError):
                message = text
            raise DaemonError(e.code, message) from None
        except urllib.error.URLError as e:
            raise DaemonUnreachable(
                f"photorigd is not reachable at {self.url} ({e.reason}); start it with "
                "`photorigd --rig RIG.yaml --data-root DIR` (docs/daemon.md), or give the address of the one that runs"
            ) from None

    def _json(self, path, body=None):
        headers = {"Content-Type": "application/json"} if body is not None else None
        data = json.dumps(body).encode() if body is not None else None
        with self._open(path, data, headers) as answer:
            return json.loads(answer.read())

    def health(self):
        return self._json("/health")

    def runs(self):
        return self._json("/runs")["runs"]

    def run(self, run_id):
        return self._json(f"/runs/{_run_id(run_id)}")

    def submit(self, recipe):
        """Queues a recipe file (its rig must be the daemon's); the run record, with its plan."""
        recipe = Path(recipe).resolve()
        return self._json("/runs", {"name": recipe.name, "recipe": recipe.read_text(), "path": str(recipe)})

    def watch(self, run_id):
        """The run's events as (event, data) pairs until its `stop`, resuming a broken stream."""
        last_id = None
        while True:
            headers = {"Last-Event-ID": last_id} if last_id else {}
            try:
                with self._open(f"/runs/{_run_id(run_id)}/events", headers=headers,
                                timeout_s=max(self.timeout_s, 60.0)) as stream:
                    event, data = "message", []
                    for raw in stream:
                        line = raw.decode("utf-8").rstrip("\r\n")
                        if line.startswith("id:"):
                            last_id = line[3:].strip()
                        elif line.startswith("event:"):
                            event = line[6:].strip()
                        elif line.startswith("data:"):
                            data.append(line[5:].lstrip())
                        elif not line and data:
                            yield event, json.loads("\n".join(data))
                            if event == "stop":
                                return
                            event, data = "message", []
            except (urllib.error.URLError, ConnectionError, TimeoutError):
                if self.run(run_id)["state"] in FINAL_STATES:
                    return

    def fetch(self, run_id, out, under=None):
        """Downloads the run's files (or those `under` a folder) into `out`, each checked
        against the size and CRC-32 the daemon lists; returns the paths written."""
        query = "?" + urllib.parse.urlencode({"under": under}) if under else ""
        listing = self._json(f"/runs/{_run_id(run_id)}/files{query}")
        written = []
        for entry in listing["files"]:
            target = Path(out) / entry["path"]
            target.parent.mkdir(parents=True, exist_ok=True)
            with self._open(f"/runs/{_run_id(run_id)}/files/{urllib.parse.quote(entry['path'])}") as answer:
                content = answer.read()
            if len(content) != entry["size"] or zlib.crc32(content) != entry["crc32"]:
                raise DaemonError(0, f"{entry['path']}: {len(content)} bytes with CRC-32 {zlib.crc32(content)}, "
                                     f"the daemon listed {entry['size']} bytes with {entry['crc32']}")
            partial = target.with_name(target.name + ".partial")
            partial.write_bytes(content)
            os.replace(partial, target)
            written.append(target)
        return written
