#!/usr/bin/python3
"""DNS rebinding and foreign pages against photorigd in a real Chromium.
Chromium resolves *.attacker.example to 127.0.0.1 (--host-resolver-rules), as
a rebinding attacker's DNS would: a page loaded as
http://127.0.0.1.rebind.attacker.example:PORT/ and one loaded as
http://page.attacker.example:PORT/ both try to list runs, read a journal,
queue a capture and abort or resume a run. Every answer the page can read is
403 (415 for a text/plain body), and the daemon's queue is the same afterwards.

Exit codes as test_browser_ui.py: 0 passed, 1 failed, 77 skipped (Chromium,
chromedriver or Selenium not installed)."""

import argparse
import json
import os
import sys
import tempfile
import time
import urllib.request

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from test_browser_ui import SKIP, api_get, browser_installed, check, shut_down, start_browser, start_chromedriver, start_daemon  # noqa: E402

RECIPE = "recipe: {name: darks}\ncapture:\n  steps:\n    - dark: {count: 2}\n"
# The run the pages try to abort or resume: paused by the test itself, so
# its state changes only if one of their requests gets through.
HELD_RECIPE = "recipe: {name: held}\ncapture:\n  steps:\n    - dark: {count: 1000}\n"

# What a page tries, from its own origin or across to the daemon's; each
# entry's status, or "refused" when the browser let the page read none.
ATTEMPTS = """
const [base, runId, recipe, done] = [arguments[0], arguments[1], arguments[2], arguments[arguments.length - 1]];
const tries = {
  list: () => fetch(base + "/api/v1/runs"),
  journal: () => fetch(base + `/api/v1/runs/${runId}/files/journal.jsonl`),
  submit: () => fetch(base + "/api/v1/runs", {method: "POST", headers: {"Content-Type": "application/json"},
                                              body: JSON.stringify({name: "darks.yaml", recipe})}),
  submit_no_cors: () => fetch(base + "/api/v1/runs", {method: "POST", mode: "no-cors", body: recipe}),
  abort: () => fetch(base + `/api/v1/runs/${runId}/abort`, {method: "POST", headers: {"Content-Type": "application/json"},
                                                            body: "{}"}),
  resume: () => fetch(base + `/api/v1/runs/${runId}/resume`, {method: "POST", headers: {"Content-Type": "application/json"},
                                                              body: "{}"}),
};
(async () => {
  const seen = {};
  for (const [name, attempt] of Object.entries(tries)) {
    try { seen[name] = (await attempt()).status; } catch (error) { seen[name] = "refused"; }
  }
  done(seen);
})();
"""


def api_post(url, path, body):
    request = urllib.request.Request(url + "api/v1" + path, method="POST", headers={"Content-Type": "application/json"},
                                     data=json.dumps(body).encode())
    with urllib.request.urlopen(request, timeout=30) as reply:
        return json.loads(reply.read() or b"{}")


def runs(url):
    return [(run["id"], run["state"]) for run in api_get(url, "/runs")["runs"]]


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--bin-dir", required=True)
    parser.add_argument("--source-dir", required=True)
    parser.add_argument("--artefacts", required=True)
    args = parser.parse_args()
    if not browser_installed():
        return SKIP

    os.makedirs(args.artefacts, exist_ok=True)
    temp = tempfile.mkdtemp(prefix="photorig-rebinding-")
    daemon, url = start_daemon(args, os.path.join(temp, "data"), os.path.join(args.artefacts, "photorigd-rebinding.log"))
    port = url.rstrip("/").rsplit(":", 1)[1]
    chromedriver = driver = None
    try:
        run_id = api_post(url, "/runs", {"name": "held.yaml", "recipe": HELD_RECIPE})["id"]
        api_post(url, f"/runs/{run_id}/pause", {})
        deadline = time.monotonic() + 30
        while dict(runs(url))[run_id] != "paused":
            check(time.monotonic() < deadline, f"the held run never paused: {runs(url)}")
            time.sleep(0.1)
        before = runs(url)

        logs = [os.path.join(args.artefacts, name) for name in ("chromedriver-rebinding.log", "chromium-rebinding.log")]
        chromedriver, chromedriver_url = start_chromedriver(*logs)
        driver = start_browser(os.path.join(temp, "profile"), chromedriver_url, logs,
                               ["--host-resolver-rules=MAP *.attacker.example 127.0.0.1"])
        driver.set_script_timeout(30)
        pages = {"rebinding": f"http://127.0.0.1.rebind.attacker.example:{port}",
                 "foreign": f"http://page.attacker.example:{port}"}
        for kind, page in pages.items():
            driver.get(page + "/")
            status = driver.execute_script("return performance.getEntriesByType('navigation')[0].responseStatus")
            check(status == 403, f"the {kind} page itself was served with status {status}")
            check("is not this daemon's" in driver.find_element("tag name", "body").text,
                  f"the {kind} page's 403 does not say why: {driver.find_element('tag name', 'body').text!r}")
            # From the page's own origin (the rebinding name reaches the daemon) and across to the daemon's.
            for base in (page, f"http://127.0.0.1:{port}"):
                seen = driver.execute_async_script(ATTEMPTS, base, run_id, RECIPE)
                print(f"{kind} page -> {base}: {seen}")
                for name, answer in seen.items():
                    # A text/plain body is refused (415) before its Host is looked at.
                    refusals = (403, 415, "refused", 0) if name == "submit_no_cors" else (403, "refused")
                    check(answer in refusals, f"{kind} page, {name} on {base}: {answer}")
                if base == page:
                    check(all(answer == 403 for name, answer in seen.items() if name != "submit_no_cors"),
                          f"{kind} page: same-origin answers are not all 403: {seen}")
            after = runs(url)
            check(after == before, f"the {kind} page changed the queue: {before} -> {after}")
        print(f"passed: the rebinding and foreign pages got 403 and the queue stayed {before}")
        return 0
    finally:
        shut_down(driver, chromedriver, (daemon,), temp)


if __name__ == "__main__":
    sys.exit(main())
