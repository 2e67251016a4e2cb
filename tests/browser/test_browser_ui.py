#!/usr/bin/python3
"""The browser interface in a real Chromium: each page opens, ps-shiny-sphere
is submitted from the Queue page and watched to `done` on the Run page, the
normal map decodes at the camera's size, the relighting canvas changes when the
light is dragged, an svbrdf run on the colour dome is relit per material as
`photorig relight --model svbrdf` renders it, and the browser logs no errors. Screenshots go to
--artefacts; --screenshots DIR also writes the README's (docs/screenshots).

Exit codes: 0 passed, 1 failed (a Chromium that is installed but does not start
fails, with chromedriver's and Chromium's own logs), 77 skipped (Chromium,
chromedriver or Selenium not installed: the reason is printed)."""

import argparse
import json
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time

SKIP = 77


def fail(message):
    print(f"FAIL: {message}", file=sys.stderr)
    sys.exit(1)


def check(condition, message):
    if not condition:
        fail(message)


def browser_installed():
    """Chromium, its driver and Selenium are there; else says which are missing (the test is then skipped)."""
    missing = [path for path in ("/usr/bin/chromium", "/usr/bin/chromedriver") if not os.path.exists(path)]
    try:
        import selenium  # noqa: F401
    except ImportError:
        missing.append("python3-selenium")
    if missing:
        print(f"SKIP: not installed: {', '.join(missing)} (scripts/install-deps.sh installs chromium, "
              "chromium-driver and python3-selenium)")
    return not missing


def shut_down(driver, chromedriver, daemons, temp):
    """The browser, its driver and the daemons stopped (SIGTERM, then kill), the temporary folder removed."""
    if driver is not None:
        driver.quit()
    if chromedriver is not None:
        chromedriver.terminate()
        chromedriver.wait(15)
    for process in (p for p in daemons if p is not None):
        process.send_signal(signal.SIGTERM)
        try:
            process.wait(15)
        except subprocess.TimeoutExpired:
            process.kill()
    shutil.rmtree(temp, ignore_errors=True)


def start_daemon(args, data_root, log_path, token=None, rig="config/rigs/sim-dome.yaml"):
    command = [os.path.join(args.bin_dir, "photorigd"), "--data-root", data_root, "--port", "0",
               "--rig", os.path.join(args.source_dir, rig),
               "--recipes", os.path.join(args.source_dir, "config/recipes")]
    log = open(log_path, "w")
    env = dict(os.environ)
    env.pop("PHOTORIG_TOKEN", None)
    if token:
        env["PHOTORIG_TOKEN"] = token
    daemon = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)
    found = {}
    ready = threading.Event()

    def pump():  # the daemon's output to its log; the address it prints noted
        for line in daemon.stdout:
            log.write(line)
            log.flush()
            match = re.search(r"photorigd: open (http://127\.0\.0\.1:\d+/)(#token=<your token>)?", line)
            if match:
                found["url"] = match.group(1)
                ready.set()
        ready.set()

    threading.Thread(target=pump, daemon=True).start()
    ready.wait(20)
    if "url" not in found:
        daemon.kill()
        fail(f"photorigd printed no address to open (log: {log_path})")
    return daemon, found["url"]


def write_hdr(path, width=32, height=16):
    """A lat-long Radiance map (flat RGBE scanlines): warm light from the
    camera's left (-x) half of the sphere of directions only."""
    import math
    rows = []
    for v in range(height):
        theta = math.pi * (v + 0.5) / height
        for u in range(width):
            phi = 2 * math.pi * (u + 0.5) / width - math.pi
            x = math.sin(theta) * math.sin(phi)
            level = 4.0 * max(0.0, -x) ** 2
            rgb = (level, 0.8 * level, 0.6 * level)
            top = max(rgb)
            if top < 1e-32:
                rows.append(bytes(4))
                continue
            exponent = math.frexp(top)[1]
            scale = 256.0 / 2 ** exponent
            rows.append(bytes([min(255, int(c * scale)) for c in rgb] + [exponent + 128]))
    with open(path, "wb") as out:
        out.write(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n" + f"-Y {height} +X {width}\n".encode() + b"".join(rows))


def write_brdf_results(folder):
    """What `photorig solve brdf` writes (report.json, samples.csv), for
    in-plane samples of a Blinn-Phong BRDF (rho_d 0.5, k_s 0.2, e 40), with a
    fit of each of the six models."""
    import json
    import math
    os.makedirs(folder)
    e, ks, rho = 40.0, 0.2, 0.5
    norm = (e + 2) * (e + 4) / (8 * math.pi * (2 ** (-e / 2) + e))
    lines = ["wi_x,wi_y,wi_z,wo_x,wo_y,wo_z,f_r,f_g,f_b,sigma_r,sigma_g,sigma_b"]
    for ti in range(10, 80, 10):
        for to in range(-80, 81, 4):
            wi = (-math.sin(math.radians(ti)), 0.0, math.cos(math.radians(ti)))
            wo = (math.sin(math.radians(to)), 0.0, math.cos(math.radians(to)))
            h = [a + b for a, b in zip(wi, wo)]
            cos_h = h[2] / math.sqrt(sum(c * c for c in h))
            f = rho / math.pi + ks * norm * cos_h ** e
            lines.append(",".join(f"{v:.6g}" for v in (*wi, *wo, f, f, f, 0.01, 0.01, 0.01)))
    candidate = lambda model, specular, shape: {  # noqa: E731  (unrounded, as a fit writes them)
        "model": model, "termination": "success", "message": "", "bic": -1234.56789, "held_out_rms": 0.0123456789,
        "cost": 0.0, "parameters": 7, "diffuse": [rho + 1.23456789e-5] * 3, "diffuse_sigma": [0.0] * 3,
        "specular": [specular] * 3, "specular_sigma": [0.0] * 3, "shape": shape, "shape_sigma": 0.0,
        "fresnel_f0": 0.0412345678, "specular2": [0.0123456789] * 3, "shape2": 3.14159265, "lobe_identifiable": True}
    report = {"samples": len(lines) - 1, "termination": "success", "chosen": "blinn_phong",
              "candidates": [candidate("lambertian", 0.0, 0.0), candidate("blinn_phong", ks, e + 1.23456789e-4),
                             candidate("ward", 0.05, 0.2123456789), candidate("ggx", 0.04, 0.2),
                             candidate("cook_torrance", 1.0, 0.3123456789), candidate("two_blinn_phong", ks, e)]}
    with open(os.path.join(folder, "report.json"), "w") as out:
        json.dump(report, out)
    with open(os.path.join(folder, "samples.csv"), "w") as out:
        out.write("\n".join(lines) + "\n")


def write_nrrd(path, n=24):
    """A raw little-endian float NRRD volume: a ball of 1 in a cube of 0."""
    import struct
    os.makedirs(os.path.dirname(path))
    values = [1.0 if (x - n / 2) ** 2 + (y - n / 2) ** 2 + (z - n / 2) ** 2 < (n / 3) ** 2 else 0.0
              for z in range(n) for y in range(n) for x in range(n)]
    header = f"NRRD0004\ntype: float\ndimension: 3\nsizes: {n} {n} {n}\nendian: little\nencoding: raw\n\n"
    with open(path, "wb") as out:
        out.write(header.encode() + struct.pack(f"<{len(values)}f", *values))


def api_get(url, path, raw=False):
    import urllib.request
    with urllib.request.urlopen(url + "api/v1" + path, timeout=30) as reply:
        body = reply.read()
        return (body, reply.headers) if raw else json.loads(body)


def submit_recipe(url, path, text):
    """A recipe submitted over the API as read from `path`; returns the run's id."""
    import urllib.request
    request = urllib.request.Request(url + "api/v1/runs", method="POST", headers={"Content-Type": "application/json"},
                                     data=json.dumps({"name": os.path.basename(path), "recipe": text, "path": path}).encode())
    with urllib.request.urlopen(request, timeout=30) as reply:
        return json.loads(reply.read())["id"]


def submit_svbrdf_run(args, url):
    """config/recipes/svbrdf-dome.yaml submitted over the API with two
    materials at most (its two paints) and without its held-out-light check
    and glTF asset: a quarter of its solve time, and nothing the relighting
    view shows is left out. Returns the run's id."""
    path = os.path.join(os.path.abspath(args.source_dir), "config/recipes/svbrdf-dome.yaml")
    text = open(path).read()
    for key in ("held_out_lights: 4", "max_materials: 3"):
        check(key in text, f"svbrdf-dome.yaml no longer says {key}")
    text = text.replace("held_out_lights: 4", "held_out_lights: -1\n      gltf: false").replace("max_materials: 3", "max_materials: 2")
    return submit_recipe(url, path, text)


def image_values(url, run_id, path):
    """A run's image from the values endpoint as a numpy array (rows, cols, channels)."""
    import numpy
    body, headers = api_get(url, f"/runs/{run_id}/values/{path}", raw=True)
    shape = (int(headers["X-Image-Height"]), int(headers["X-Image-Width"]), int(headers["X-Image-Channels"]))
    return numpy.frombuffer(body, dtype="<f4").reshape(shape)


def canvas_rgb(driver, canvas):
    """The pixels a canvas shows, as a numpy uint8 array (rows, cols, 3)."""
    import base64
    import io
    import numpy
    from PIL import Image
    data_url = driver.execute_script("return arguments[0].toDataURL('image/png')", canvas)
    return numpy.asarray(Image.open(io.BytesIO(base64.b64decode(data_url.split(",", 1)[1]))).convert("RGB")).astype(int)


def check_per_material_relighting(args, driver, url, run_id, data_root, screenshot, phase):
    """A run solved with svbrdf: the relighting view offers the per-material
    model and shows it first, redraws when the light moves, adds the lobe on
    the glossy paint only (against the Lambertian render of the same colour
    albedo), and agrees with `photorig relight --model svbrdf` for the light
    it was left at (checked to be away from every LED of the run)."""
    import numpy
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support.ui import Select, WebDriverWait
    wait = lambda seconds, condition, what: WebDriverWait(driver, seconds).until(  # noqa: E731
        lambda d: condition(d), message=what)

    deadline = time.monotonic() + 180
    while (run := api_get(url, f"/runs/{run_id}"))["state"] not in ("done", "failed", "aborted", "interrupted"):
        check(time.monotonic() < deadline, f"svbrdf run {run_id} still {run['state']} after 180 s")
        time.sleep(0.5)
    check(run["state"] == "done", f"svbrdf run {run_id} ended {run['state']}: {run.get('reason')}")
    phase("svbrdf run done")
    report = api_get(url, f"/runs/{run_id}/files/results/svbrdf/report.json")
    lobes = [m for m in report["materials"] if m["model"] != "lambertian"]
    check(lobes, f"the svbrdf fit found no material with a lobe: {report['materials']}")
    glossy = max(range(len(report["materials"])), key=lambda i: sum(report["materials"][i]["specular"]))
    matte = min(range(len(report["materials"])), key=lambda i: sum(report["materials"][i]["specular"]))

    driver.get(url + f"#/results/{run_id}")
    canvas = wait(60, lambda d: d.find_elements(By.ID, "relight-canvas"), "no relighting canvas for the svbrdf run")[0]
    model = Select(driver.find_element(By.ID, "relight-model"))
    check(model.first_selected_option.get_attribute("value") == "3",
          f"the per-material model is not shown first: {model.first_selected_option.text!r}")
    check("materials" in [s.get_attribute("id") for s in driver.find_elements(By.CSS_SELECTOR, "section")],
          "no materials table for the svbrdf run")
    check(driver.find_element(By.CSS_SELECTOR, "#materials h2 .verdict").get_attribute("data-verdict") == "complete",
          "the svbrdf materials are not headed by a complete capture")
    # The svbrdf fit's own figures, readable, beside its photometric stereo's.
    metrics = wait(15, lambda d: d.find_elements(By.CSS_SELECTOR, 'section.metrics[data-folder="results/svbrdf/"]'),
                   "no metrics of the svbrdf fit")[0].text
    chi2 = report["noise"]["reduced_chi_square"]
    for expected in (f"fitted {report['pixels']['fitted']}", f"reduced chi-square {float(f'{chi2:.4g}'):g}"):
        check(expected in metrics, f"the svbrdf metrics lack {expected!r}: {metrics}")
    for section in driver.find_elements(By.CSS_SELECTOR, "section.metrics"):
        check("{" not in section.text and '"' not in section.text, f"raw JSON in the metrics: {section.text}")
    pad = driver.find_element(By.ID, "light-pad")
    js = driver.execute_script
    js("arguments[0].scrollIntoView({block: 'center'})", canvas)
    before = canvas_rgb(driver, canvas)
    ActionChains(driver).move_to_element_with_offset(pad, -30, -38).click().perform()  # 11 deg from the nearest LED
    per_material = canvas_rgb(driver, canvas)
    check(numpy.abs(per_material - before).max() > 20, "the per-material canvas did not change when the light moved")
    screenshot("relight-per-material", driver.find_element(By.ID, "relight"))
    light = [float(v) for v in canvas.get_attribute("data-light").split(",")]
    white = float(canvas.get_attribute("data-white"))
    model.select_by_value("0")
    lambertian = canvas_rgb(driver, canvas)
    model.select_by_value("3")

    # The lobe adds light on the glossy paint, next to nothing on the matte one
    # (compared in linear units: in gamma-encoded levels a weak white lobe
    # shows large where a channel of the paint is dark, e.g. orange's blue).
    material = image_values(url, run_id, "results/svbrdf/material.png")[:, :, 0]
    linear = lambda levels: (levels / 255.0) ** 2.2  # noqa: E731
    added = (linear(per_material) - linear(lambertian)).mean(axis=2)
    on_glossy, on_matte = added[material == glossy], added[material == matte]
    print(f"per-material minus Lambertian (linear, white = 1): glossy material {glossy}: mean {on_glossy.mean():.4f}, "
          f"{(on_glossy >= 0.1).sum()} of {on_glossy.size} pixels >= 0.1; matte material {matte}: mean {on_matte.mean():.4f}, "
          f"largest {on_matte.max():.3f}", flush=True)
    check((on_glossy >= 0.1).sum() >= 50, "the per-material render does not add a highlight on the glossy material")
    check(on_glossy.mean() > 5 * on_matte.mean(), "the per-material render adds about as much on the matte material")

    # Pixels the fit left without a material inside the object (mixed ones,
    # some under the highlight) are shaded, not black holes.
    fitted = material != 255
    inside = ~fitted
    for axis in (0, 1):
        inside &= numpy.maximum.accumulate(fitted, axis=axis) & numpy.flip(
            numpy.maximum.accumulate(numpy.flip(fitted, axis), axis=axis), axis)
    shaded = per_material[inside].max(axis=1) > 10
    print(f"unfitted pixels inside the object: {inside.sum()}, {shaded.sum()} of them shaded", flush=True)
    check(shaded.all() if inside.sum() < 20 else shaded.mean() > 0.95,
          f"unfitted pixels inside the object drawn black: {(~shaded).sum()} of {inside.sum()}")

    check_matches_photorig_relight(args, url, run_id, data_root, per_material, light, white, material, "blinn_phong")

    # The GGX branch (Fresnel, masking): the glossy material's lobe swapped in
    # report.json for a GGX one, the page reloaded and compared again.
    report_file = os.path.join(data_root, "runs", run_id, "results", "svbrdf", "report.json")
    report["materials"][glossy].update(model="ggx", specular=[0.3, 0.25, 0.2], shape=0.25)
    with open(report_file, "w") as out:
        json.dump(report, out)
    driver.refresh()
    canvas = wait(60, lambda d: d.find_elements(By.ID, "relight-canvas"), "no relighting canvas after the lobe changed")[0]
    check("ggx" in Select(driver.find_element(By.ID, "relight-model")).first_selected_option.text,
          "the per-material model does not name the GGX lobe")
    js("arguments[0].scrollIntoView({block: 'center'})", canvas)
    ActionChains(driver).move_to_element_with_offset(driver.find_element(By.ID, "light-pad"), -30, -38).click().perform()
    light = [float(v) for v in canvas.get_attribute("data-light").split(",")]
    check_matches_photorig_relight(args, url, run_id, data_root, canvas_rgb(driver, canvas), light,
                                   float(canvas.get_attribute("data-white")), material, "ggx")
    for box in driver.find_elements(By.CSS_SELECTOR, "#page .error"):
        fail(f"the svbrdf Results page shows an error: {box.text}")
    errors = [entry for entry in driver.get_log("browser") if entry["level"] == "SEVERE"]
    check(not errors, "the browser logged errors on the svbrdf run:\n" + "\n".join(e["message"] for e in errors))
    phase("per-material relighting")


def check_matches_photorig_relight(args, url, run_id, data_root, shown, light, white, material, lobe):
    """The canvas `shown` against `photorig relight --model svbrdf` for the
    same light, held out (more than 5 deg from every LED of the run), tone-mapped
    as the page does it: white = `white` (linear, after the page's factor
    pi), gamma 2.2; over the pixels the fit kept."""
    import numpy
    leds = [led["direction"] for led in api_get(url, f"/runs/{run_id}/files/manifest.json")["lights"]]
    nearest_deg = min(numpy.degrees(numpy.arccos(numpy.clip(numpy.dot(light, d) / numpy.linalg.norm(d), -1, 1))) for d in leds)
    check(nearest_deg > 5, f"the light {light} is within {nearest_deg:.1f} deg of an LED: not a held-out direction")
    relit_file = os.path.join(data_root, "runs", run_id, "results", "relit-check", f"{lobe}.tiff")
    os.makedirs(os.path.dirname(relit_file), exist_ok=True)
    done = subprocess.run([os.path.join(args.bin_dir, "photorig"), "relight", "--run", os.path.join(data_root, "runs", run_id),
                           "--light", ",".join(f"{v:.9g}" for v in light), "--model", "svbrdf", "--out", relit_file],
                          capture_output=True, text=True, timeout=60)
    check(done.returncode == 0, f"photorig relight failed: {done.stderr}")
    relit = image_values(url, run_id, f"results/relit-check/{lobe}.tiff")
    expected = 255 * numpy.clip(numpy.pi * relit / white, 0, 1) ** (1 / 2.2)
    fitted = material < 255
    difference = numpy.abs(shown[fitted] - expected[fitted])
    print(f"page against photorig relight, {lobe} lobe, light ({', '.join(f'{v:.3f}' for v in light)}; {nearest_deg:.1f} deg "
          f"from the nearest LED), {fitted.sum()} pixels: mean {difference.mean():.2f} levels, 99th percentile "
          f"{numpy.percentile(difference, 99):.1f}, largest {difference.max():.1f}", flush=True)
    check(difference.mean() < 0.75 and numpy.percentile(difference, 99) <= 2.0,
          f"the page's per-material render ({lobe}) departs from photorig relight --model svbrdf")


def log_tail(path, lines=40):
    """The end of a log without the D-Bus complaints a headless Chromium makes
    where no session bus runs (they say nothing about why it failed)."""
    if not os.path.exists(path):
        return f"(no {os.path.basename(path)})"
    kept = [line for line in open(path, errors="replace").read().splitlines() if "dbus" not in line]
    return "\n".join(kept[-lines:])


def start_chromedriver(log_path, output_path):
    """chromedriver on a free port of 127.0.0.1, started here rather than by
    Selenium, which waits for it at "localhost" and hides why it did not come
    up; its log names the reason, and Chromium's own output lands beside it."""
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    with open(output_path, "wb") as output:
        process = subprocess.Popen(["/usr/bin/chromedriver", f"--port={port}", f"--log-path={log_path}", "--verbose"],
                                   stdout=output, stderr=subprocess.STDOUT)
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        if process.poll() is not None:
            break
        try:
            socket.create_connection(("127.0.0.1", port), timeout=1).close()
            return process, f"http://127.0.0.1:{port}"
        except OSError:
            time.sleep(0.2)
    process.kill()
    fail(f"chromedriver did not listen on 127.0.0.1:{port} (exit {process.poll()}); its log:\n{log_tail(log_path)}")


def start_browser(profile_dir, chromedriver_url, log_paths, extra_flags=()):
    from selenium import webdriver

    options = webdriver.ChromeOptions()
    options.binary_location = "/usr/bin/chromium"
    # DevTools over a pipe, not a TCP port: chromedriver reaches a port at
    # "localhost", which does not resolve where /etc/hosts is missing (a
    # pristine container), and the session then fails with "unable to
    # connect to renderer".
    for flag in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage", f"--user-data-dir={profile_dir}",
                 "--window-size=1280,1000", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
                 "--no-first-run", "--disable-extensions", "--disable-background-networking",
                 "--remote-debugging-pipe", *extra_flags):
        options.add_argument(flag)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    try:
        return webdriver.Remote(command_executor=chromedriver_url, options=options)
    except Exception as error:
        for path in log_paths:
            print(f"--- {path}:\n{log_tail(path)}", flush=True)
        fail(f"Chromium did not start under chromedriver: {str(error).splitlines()[0]}")


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--bin-dir", required=True)
    parser.add_argument("--source-dir", required=True)
    parser.add_argument("--artefacts", required=True)
    parser.add_argument("--screenshots", help="also write the README's screenshots here")
    args = parser.parse_args()

    if not browser_installed():
        return SKIP
    from selenium.common.exceptions import StaleElementReferenceException
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support.ui import Select, WebDriverWait

    os.makedirs(args.artefacts, exist_ok=True)
    started = time.monotonic()
    temp = tempfile.mkdtemp(prefix="photorig-browser-")
    daemon, url = start_daemon(args, os.path.join(temp, "data"), os.path.join(args.artefacts, "photorigd.log"))
    driver = None
    chromedriver = None
    colour = None
    try:
        # The colour dome's daemon solves an svbrdf run meanwhile (checked after the other pages).
        colour_root = os.path.join(temp, "data-colour")
        colour, colour_url = start_daemon(args, colour_root, os.path.join(args.artefacts, "photorigd-colour.log"),
                                          rig="config/rigs/sim-dome-colour.yaml")
        svbrdf_run = submit_svbrdf_run(args, colour_url)
        driver_logs = [os.path.join(args.artefacts, name) for name in ("chromedriver.log", "chromium-output.log")]
        chromedriver, chromedriver_url = start_chromedriver(*driver_logs)
        driver = start_browser(os.path.join(temp, "chromium-profile"), chromedriver_url, driver_logs)
        # The pages re-render as the daemon's state moves on: an element found
        # may be replaced before it is read, so a condition that meets a stale
        # one is asked again.
        wait = lambda seconds, condition, what: WebDriverWait(  # noqa: E731
            driver, seconds, ignored_exceptions=[StaleElementReferenceException]).until(
            lambda d: condition(d), message=what)
        shots = {}

        def screenshot(name, element=None):
            path = os.path.join(args.artefacts, f"{name}.png")
            if element is None:
                driver.save_screenshot(path)
            else:
                driver.execute_script("arguments[0].scrollIntoView()", element)
                element.screenshot(path)
            shots[name] = path

        js = driver.execute_script
        phase = lambda name: print(f"{time.monotonic() - started:6.1f} s  {name}", flush=True)  # noqa: E731
        phase("browser started")

        # Rig page: devices and free disk.
        driver.get(url)
        wait(15, lambda d: d.find_elements(By.ID, "free-disk"), "the Rig page shows no devices")
        devices = js("return fetch('/api/v1/devices').then(r => r.json())")
        camera = next(d for d in devices["devices"] if d["role"] == "camera")
        check("sim-dome" in driver.find_element(By.ID, "devices").text, "the Rig page does not name the rig")
        # Before the first frame: a placeholder, no <img> without a picture (a broken-image icon).
        wait(5, lambda d: "no frame taken" in d.find_element(By.ID, "frame-placeholder").text, "no frame placeholder on the Rig page")
        check(not driver.find_element(By.ID, "frame-image").is_displayed(), "the Rig page shows an image before any frame")

        phase("rig page")
        # Queue page: choose the recipe, see its plan, submit.
        driver.get(url + "#/queue")
        select = wait(15, lambda d: d.find_elements(By.ID, "recipe-select"), "no recipe list on the Queue page")[0]
        wait(10, lambda d: len(Select(select).options) > 1, "the recipe list is empty")
        Select(select).select_by_visible_text(next(o.text for o in Select(select).options if o.text.startswith("ps-shiny-sphere ")))
        frames = wait(20, lambda d: d.find_elements(By.ID, "plan-frames"), "no dry-run plan shown")[0]
        check(frames.text == "49", f"the plan of ps-shiny-sphere shows {frames.text} frames, expected 49 (dark + 48 LEDs)")
        screenshot("queue")
        # Every frame the Run page shows, noted as it loads with the run's state then
        # (the page is not reloaded from here on: the route changes, the document stays).
        js("""window.framesShown = [];
              document.addEventListener('load', (event) => {
                if (event.target.id !== 'frame-image') return;
                // The Rig page shows frames too, without a journal: only the Run page's count.
                const state = document.querySelector('#run-state [data-state]');
                const journal = document.getElementById('run-journal');
                if (!journal) return;
                window.framesShown.push({file: event.target.dataset.file, width: event.target.naturalWidth,
                  state: state && state.dataset.state, journal: journal.textContent});
              }, true);""")
        driver.find_element(By.ID, "submit").click()

        phase("submitted")
        # Run page: watched from the event stream until done.
        wait(15, lambda d: "#/run/" in d.current_url, "submitting did not open the Run page")
        run_id = driver.current_url.split("#/run/")[1]
        wait(120, lambda d: d.find_elements(By.CSS_SELECTOR, "#run-state [data-state=done]")
             or d.find_elements(By.CSS_SELECTOR, "#run-state .state-failed"), "the run did not finish")
        state = driver.find_element(By.ID, "run-state").text
        check(state == "done", f"run {run_id} ended {state}: {driver.find_element(By.ID, 'run-reason').text}")
        check(driver.find_element(By.ID, "run-counters").text.startswith("49/49 frames"),
              f"the Run page counts {driver.find_element(By.ID, 'run-counters').text!r}")
        wait(15, lambda d: d.find_element(By.ID, "frame-image").get_attribute("data-file"), "no latest frame shown")
        wait(15, lambda d: "frames/0048" in d.find_element(By.ID, "run-journal").text, "the journal lacks the last frame")
        shown = js("return window.framesShown")
        live = [f for f in shown if f["state"] == "running" and f["width"] > 0]
        files = sorted({f["file"] for f in live})
        print(f"run page: {len(files)} distinct frames shown while capturing ({', '.join(files)}); {len(shown)} in all", flush=True)
        check(len(files) >= 5, f"the Run page showed {len(files)} distinct frames during the 49-frame capture, expected 5 or more")
        check(all(f["file"].split("/")[-1].split(".")[0] in f["journal"] for f in live),
              "a frame was shown while the journal beside it lacked it")
        wait(10, lambda d: d.find_element(By.CSS_SELECTOR, "#run-verdict [data-verdict]").get_attribute("data-verdict") == "complete",
             "the Run page does not say the capture was complete")
        for button in driver.find_elements(By.CSS_SELECTOR, "button[data-action]"):
            check(not button.is_enabled(), f"{button.text} stays enabled on the finished run")
        screenshot("run")

        phase("run done")
        # Rig page again: the last frame of the run with its histogram.
        driver.get(url + "#/rig")
        wait(15, lambda d: d.find_element(By.ID, "frame-image").get_attribute("data-file"), "the Rig page shows no frame")
        wait(15, lambda d: "clipped" in d.find_element(By.ID, "frame-caption").text, "no frame caption")
        screenshot("rig")

        phase("rig page with frame")
        # A run aborted from its Run page (ps-shiny-sphere's LEDs six times over,
        # unsolved: time to press abort): its controls disabled once it ended, and
        # the capture's verdict beside the results written into it.
        recipe_path = os.path.join(os.path.abspath(args.source_dir), "config/recipes/ps-shiny-sphere.yaml")
        text = open(recipe_path).read()
        check("    - each_led: {leds: all}\n" in text and "\nsolve:" in text, "ps-shiny-sphere.yaml no longer reads as expected")
        text = text.replace("    - each_led: {leds: all}\n", "    - each_led: {leds: all}\n" * 6).split("\nsolve:")[0]
        aborted_run = submit_recipe(url, recipe_path, text)
        driver.get(url + f"#/run/{aborted_run}")
        wait(60, lambda d: d.find_element(By.ID, "frame-image").get_attribute("data-file"), "the run to abort shows no frame")
        driver.find_element(By.CSS_SELECTOR, "button[data-action=abort]").click()
        wait(30, lambda d: d.find_elements(By.CSS_SELECTOR, "#run-state [data-state=aborted]"), "the run did not end aborted")
        verdict = wait(10, lambda d: [e.text for e in
                                      d.find_elements(By.CSS_SELECTOR, "#run-verdict [data-verdict=aborted]")],
                       "the Run page does not say the capture was aborted")[0]
        for button in driver.find_elements(By.CSS_SELECTOR, "button[data-action]"):
            check(not button.is_enabled(), f"{button.text} stays enabled on the aborted run")
        write_brdf_results(os.path.join(temp, "data", "runs", aborted_run, "results", "brdf"))
        driver.get(url + f"#/results/{aborted_run}")
        brdf_heading = wait(30, lambda d: d.find_elements(By.CSS_SELECTOR, "#brdf h2 .verdict"), "no verdict beside the aborted run's BRDF")[0]
        check(brdf_heading.get_attribute("data-verdict") == "aborted" and brdf_heading.text == verdict,
              f"the aborted run's BRDF result reads {brdf_heading.text!r}, its Run page {verdict!r}")
        print(f"aborted run: {verdict}", flush=True)

        phase("aborted run")
        # Results page: the normal map at the camera's size, read-out, relighting.
        envmap_dir = os.path.join(temp, "data", "runs", run_id, "results", "envmaps")
        os.makedirs(envmap_dir)
        write_hdr(os.path.join(envmap_dir, "sky-left.hdr"))
        results_dir = os.path.dirname(envmap_dir)
        write_brdf_results(os.path.join(results_dir, "brdf"))
        write_nrrd(os.path.join(results_dir, "tomography", "volume.nrrd"))
        driver.get(url + f"#/results/{run_id}")
        image = wait(30, lambda d: d.find_elements(By.CSS_SELECTOR, "#map-image[data-map=normals]"), "no normal map")[0]
        size = wait(15, lambda d: js("const i = arguments[0]; return i.complete && i.naturalWidth ? [i.naturalWidth, i.naturalHeight] : null", image),
                    "the normal map did not decode")
        check(size == [camera["width"], camera["height"]],
              f"the normal map decodes at {size}, the camera is {camera['width']}x{camera['height']}")
        phase("results page loaded")
        canvas = wait(30, lambda d: d.find_elements(By.ID, "relight-canvas"), "no relighting canvas")[0]
        wait(30, lambda d: d.find_elements(By.ID, "mesh-canvas"), "no mesh view")
        wait(30, lambda d: d.find_elements(By.CSS_SELECTOR, "section.volume canvas"), "no volume slices")
        js("arguments[0].scrollIntoView({block: 'center'})", image)
        ActionChains(driver).move_to_element(image).perform()
        wait(10, lambda d: "n = (" in d.find_element(By.ID, "map-readout").text, "no value read out under the cursor")
        readout = driver.find_element(By.ID, "map-readout").text
        nz = float(re.search(r"n = \(([^,]+), ([^,]+), ([^)]+)\)", readout).group(3))
        check(nz > 0.9, f"the sphere's centre should face the camera: {readout}")
        # Every other map shows with its legend and reads out under the cursor.
        def hover_pixel(x, y):  # the map's pixel (x, y), whatever its displayed size
            image = driver.find_element(By.ID, "map-image")
            js("arguments[0].scrollIntoView({block: 'center'})", image)
            box = js("const r = arguments[0].getBoundingClientRect(); return [r.width, r.height, arguments[0].naturalWidth]", image)
            scale = box[0] / box[2]
            ActionChains(driver).move_to_element_with_offset(
                image, int((x + 0.5) * scale - box[0] / 2), int((y + 0.5) * scale - box[1] / 2)).perform()

        legends = {}
        for button in driver.find_elements(By.CSS_SELECTOR, "#maps button[data-map]"):
            key = button.get_attribute("data-map")
            button.click()
            wait(15, lambda d: d.find_element(By.ID, "map-image").get_attribute("data-map") == key
                 and js("const i = arguments[0]; return i.complete && i.naturalWidth > 0", d.find_element(By.ID, "map-image")),
                 f"map {key} not shown")
            js("document.getElementById('map-readout').textContent = ''")
            hovers = []

            def read_out(d):  # the cursor moved by a pixel each time: the values may arrive after the first move
                hovers.append(1)
                hover_pixel(camera["width"] // 2 + len(hovers) % 2, camera["height"] // 2)
                return d.find_element(By.ID, "map-readout").text.startswith("(") and d.find_element(By.ID, "map-legend").text
            wait(15, read_out, f"map {key}: no read-out or legend")
            legends[key] = driver.find_element(By.ID, "map-legend").text
            if key == "flags":
                check("solved" in driver.find_element(By.ID, "map-readout").text,
                      f"the flag at the sphere's centre reads {driver.find_element(By.ID, 'map-readout').text!r}")
            if key == "albedo":
                screenshot("maps", driver.find_element(By.ID, "maps"))
        # The lobe's rho_s and exponent each on its own scale: the page's range
        # is each channel's minimum .. 99.5th percentile over the pixels with a lobe.
        import numpy
        check({"rho_s", "exponent"} <= legends.keys(), f"no rho_s and exponent maps: {sorted(legends)}")
        ps_folder = driver.find_element(By.CSS_SELECTOR, "#maps h2").text.split("(")[1].split(")")[0]
        lobe = image_values(url, run_id, f"{ps_folder}specular.tiff")
        has_lobe = (lobe[:, :, 0] > 0) & numpy.isfinite(lobe[:, :, 1])
        ranges = {}
        for key, channel in (("rho_s", 0), ("exponent", 1)):
            low, high = (float(v) for v in re.match(r"(\S+) … (\S+);", legends[key]).groups())
            values = numpy.sort(lobe[:, :, channel][has_lobe])
            expected = (values[0], values[int(0.995 * (len(values) - 1))])
            check(numpy.allclose((low, high), expected, rtol=1e-3),
                  f"the {key} map spans {low} .. {high}, its values {expected[0]:.4g} .. {expected[1]:.4g}")
            ranges[key] = high
        print(f"lobe maps: rho_s up to {ranges['rho_s']:.3g}, exponent up to {ranges['exponent']:.3g}", flush=True)
        check(ranges["exponent"] > 10 * ranges["rho_s"], f"rho_s and exponent read alike: {ranges}")
        for section in driver.find_elements(By.CSS_SELECTOR, "section.metrics"):
            check("{" not in section.text and '"' not in section.text, f"raw JSON in the metrics: {section.text}")
        verdict = driver.find_element(By.CSS_SELECTOR, "#maps h2 .verdict")
        check(verdict.get_attribute("data-verdict") == "complete", f"the maps are headed {verdict.text!r}")
        before = js("return arguments[0].toDataURL()", canvas)
        pad = driver.find_element(By.ID, "light-pad")
        ActionChains(driver).move_to_element_with_offset(pad, -50, 0).click_and_hold().move_by_offset(100, -30).release().perform()
        after = js("return arguments[0].toDataURL()", canvas)
        check(before != after, "the relighting canvas did not change when the light moved")
        brightness = """const c = document.createElement('canvas'); const s = arguments[0];
            c.width = s.width; c.height = s.height; const g = c.getContext('2d'); g.drawImage(s, 0, 0);
            const d = g.getImageData(0, 0, c.width, c.height).data; let n = 0, left = 0, right = 0;
            for (let i = 0; i < d.length; i += 4) {
              n += d[i] > 40;
              if ((i / 4) % c.width < c.width / 2) left += d[i]; else right += d[i];
            }
            return [n, left, right];"""
        lit = js(brightness, canvas)[0]
        check(lit > 0.2 * camera["width"] * camera["height"], f"the relit sphere is dark: {lit} bright pixels")
        screenshot("results")
        screenshot("relight", driver.find_element(By.ID, "relight"))

        phase("relit")
        # The environment map in the run's results lights the sphere from the left.
        Select(driver.find_element(By.ID, "relight-model")).select_by_value("2")
        wait(15, lambda d: js(brightness, canvas)[1] > 1.5 * js(brightness, canvas)[2],
             "the sky brightest on the left does not light the sphere's left half most")
        screenshot("relight-envmap", driver.find_element(By.ID, "relight"))

        phase("environment map")
        # BRDF results: the polar plot of samples and fitted lobes; a volume's slices.
        wait(15, lambda d: d.find_elements(By.ID, "brdf-polar"), "no BRDF polar plot")
        check("chosen blinn_phong" in driver.find_element(By.ID, "brdf").text, "the BRDF section does not name the chosen model")
        # Each of the six models in its own colour, its lobe drawn, its parameters rounded.
        datasets = driver.execute_async_script("""const done = arguments[arguments.length - 1];
            import('/vendor/chart.js/chart.esm.js').then(({ Chart }) => done(Chart.getChart(document.getElementById('brdf-polar'))
              .data.datasets.map((d) => [d.label.split(' ')[0], d.borderColor, d.backgroundColor, d.data.map((p) => p.y)])));""")
        colours = [d[1] for d in datasets]
        check(len(datasets) == 7 and len(set(colours)) == 7 and all(d[1] == d[2] for d in datasets),
              f"the BRDF plot's colours: {[(d[0], d[1], d[2]) for d in datasets]}")
        curves = {d[0]: numpy.array(d[3]) for d in datasets}
        for model in ("blinn_phong", "ward", "ggx", "cook_torrance", "two_blinn_phong"):
            check(curves[model].max() > 1.2 * curves["lambertian"].max(), f"the {model} curve shows no lobe above the Lambertian one")
        rows = {r.find_elements(By.TAG_NAME, "td")[0].text: r.text for r in driver.find_elements(By.CSS_SELECTOR, "#brdf tr")[1:]}
        for model, expected in (("blinn_phong", "rho_d 0.5, 0.5, 0.5; k_s 0.2, 0.2, 0.2; exponent 40"),
                                ("ward", "rho_s 0.05, 0.05, 0.05; alpha 0.212"), ("cook_torrance", "m 0.312; F0 0.0412"),
                                ("two_blinn_phong", "k_s2 0.0123, 0.0123, 0.0123; exponent2 3.14")):
            check(expected in rows[model], f"the BRDF table's {model} row reads {rows[model]!r}, expected {expected!r} in it")
        check("0.01235 -1235" in rows["ggx"], f"held-out rms and BIC not rounded: {rows['ggx']!r}")
        screenshot("brdf", driver.find_element(By.ID, "brdf"))
        volume = wait(15, lambda d: d.find_elements(By.CSS_SELECTOR, "section.volume canvas"), "no volume slices")[0]
        centre, corner = js("""const c = arguments[0], d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
                               const at = (x, y) => d[4 * (y * c.width + x)];
                               return [at(c.width >> 1, c.height >> 1), at(0, 0)];""", volume)
        check(centre == 255 and corner == 0, f"the volume's middle slice shows {centre} at the ball's centre, {corner} outside")
        for box in driver.find_elements(By.CSS_SELECTOR, "#page .error"):
            fail(f"the Results page shows an error: {box.text}")

        phase("BRDF and volume")
        page_bytes = js("""return performance.getEntriesByType('resource').concat(performance.getEntriesByType('navigation'))
                           .filter(e => !e.name.includes('/api/')).reduce((s, e) => s + (e.transferSize || e.encodedBodySize || 0), 0)""")
        print(f"results page: {page_bytes / 1024:.0f} KiB of pages and libraries")

        # Every page logged no errors.
        errors = [entry for entry in driver.get_log("browser") if entry["level"] == "SEVERE"]
        check(not errors, "the browser logged errors:\n" + "\n".join(e["message"] for e in errors))

        check_per_material_relighting(args, driver, colour_url, svbrdf_run, colour_root, screenshot, phase)

        # A daemon with a token: given once in the address, kept for the tab, gone from the address.
        token = "browser-test-token-0123456789"
        secured, secured_url = start_daemon(args, os.path.join(temp, "data-token"),
                                            os.path.join(args.artefacts, "photorigd-token.log"), token)
        try:
            driver.get(secured_url + "#token=" + token)
            wait(15, lambda d: d.find_elements(By.ID, "free-disk"), "the Rig page shows no devices with a token")
            check(js("return sessionStorage.getItem('photorig.token')") == token, "the token was not kept")
            check("token" not in driver.current_url, f"the token stays in the address: {driver.current_url}")
            errors = [entry for entry in driver.get_log("browser") if entry["level"] == "SEVERE"]
            check(not errors, "the browser logged errors with a token:\n" + "\n".join(e["message"] for e in errors))
        finally:
            secured.send_signal(signal.SIGTERM)
            secured.wait(15)
        phase("token")

        if args.screenshots:  # the README's, in 128 colours to keep the repository small
            from PIL import Image
            os.makedirs(args.screenshots, exist_ok=True)
            for name in ("queue", "run", "relight", "relight-per-material"):
                Image.open(shots[name]).convert("RGB").quantize(128).save(
                    os.path.join(args.screenshots, f"ui-{name}.png"), optimize=True)
        print(f"passed in {time.monotonic() - started:.1f} s; screenshots in {args.artefacts}")
        return 0
    finally:
        shut_down(driver, chromedriver, (daemon, colour), temp)


if __name__ == "__main__":
    sys.exit(main())
