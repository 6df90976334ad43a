#!/usr/bin/python3
"""The coordinator's dashboard in a real browser: a coordinator (with a token) and a worker, two
jobs, and headless Chromium driven through chromium-driver's WebDriver protocol (plain HTTP,
no Selenium). It logs in, reads the job list (a job named <script>... shows as text), cancels
the second job, watches the first one's preview while it renders and its result when it is
done, and opens the workers and bench pages; assertions are on the DOM. A screenshot of each
page goes to BUILD_DIR/dashboard-screenshots/.

usage: test_dashboard.py BUILD_DIR SOURCE_DIR
"""

import base64
import json
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import time
import urllib.error
import urllib.request

TOKEN = "dashboard-test-token"
EVIL = "<script>window.pwned=1</script><img src=x onerror=window.pwned=2>"


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def wait_for(what, fn, timeout=60.0, interval=0.2):
    deadline = time.time() + timeout
    last = None
    while time.time() < deadline:
        try:
            last = fn()
            if last:
                return last
        except Exception as e:  # a page mid-refresh: try again
            last = e
        time.sleep(interval)
    raise AssertionError("timed out waiting for {0} (last: {1!r})".format(what, last))


class WebDriver:
    """The few WebDriver commands this test needs (W3C protocol over HTTP)."""

    def __init__(self, port):
        self.base = "http://127.0.0.1:{0}".format(port)
        caps = {"capabilities": {"alwaysMatch": {
            "browserName": "chrome",
            "goog:chromeOptions": {"binary": shutil.which("chromium") or "/usr/bin/chromium",
                                   "args": ["--headless=new", "--no-sandbox", "--disable-gpu",
                                            "--disable-dev-shm-usage", "--window-size=1280,1000"]}}}}
        self.session = self._send("POST", "/session", caps)["sessionId"]

    def _send(self, method, path, body=None):
        data = json.dumps(body).encode() if body is not None else None
        req = urllib.request.Request(self.base + path, data=data, method=method,
                                     headers={"Content-Type": "application/json"})
        try:
            with urllib.request.urlopen(req, timeout=60) as r:
                return json.loads(r.read())["value"]
        except urllib.error.HTTPError as e:
            raise RuntimeError("webdriver {0} {1}: {2}".format(method, path, e.read()[:500]))

    def cmd(self, method, path, body=None):
        return self._send(method, "/session/" + self.session + path, body)

    def get(self, url):
        self.cmd("POST", "/url", {"url": url})

    def url(self):
        return self.cmd("GET", "/url")

    def js(self, script, *args):
        return self.cmd("POST", "/execute/sync", {"script": script, "args": list(args)})

    def find(self, css):
        return self.cmd("POST", "/element", {"using": "css selector", "value": css})

    def click(self, css):
        elem = self.find(css)
        self.cmd("POST", "/element/" + list(elem.values())[0] + "/click", {})

    def type(self, css, text, clear=False):
        elem = list(self.find(css).values())[0]
        if clear:
            self.cmd("POST", "/element/" + elem + "/clear", {})
        self.cmd("POST", "/element/" + elem + "/value", {"text": text})

    def screenshot(self, path):
        with open(path, "wb") as f:
            f.write(base64.b64decode(self.cmd("GET", "/screenshot")))
        print("screenshot:", path)

    def quit(self):
        try:
            self._send("DELETE", "/session/" + self.session)
        except Exception:
            pass


def http(url, method="GET", headers=None, data=None):
    req = urllib.request.Request(url, method=method, headers=headers or {}, data=data)
    try:
        with urllib.request.urlopen(req, timeout=30) as r:
            return r.status, r.read()
    except urllib.error.HTTPError as e:
        return e.code, e.read()


def main():
    build, source = os.path.abspath(sys.argv[1]), os.path.abspath(sys.argv[2])
    shots = os.path.join(build, "dashboard-screenshots")
    os.makedirs(shots, exist_ok=True)
    work = tempfile.mkdtemp(prefix="lightfarm-dashboard-")
    procs = []
    driver = None
    try:
        with open(os.path.join(work, "token"), "w") as f:
            f.write(TOKEN + "\n")
        scene = os.path.join(source, "scenes", "cornell-box", "scene.pbrt")
        cli = os.path.join(build, "lightfarm")

        # Bench results for the error-versus-time page.
        bench = os.path.join(work, "bench", "cornell-box")
        subprocess.run([cli, "bench", scene, "--out-dir", bench, "--methods", "brute,lightcuts", "--lights", "400",
                        "--resolution", "16x16", "--repeats", "1", "--truth", "none", "--no-plots", "--threads", "1"],
                       check=True, stdout=subprocess.DEVNULL)

        coord_out = os.path.join(work, "coordinator.out")
        procs.append(subprocess.Popen(
            [os.path.join(build, "lightfarm-coordinator"), "--listen", "127.0.0.1:0", "--state-dir",
             os.path.join(work, "state"), "--token-file", os.path.join(work, "token"), "--http-listen", "127.0.0.1:0",
             "--bench-dir", os.path.join(work, "bench"), "--max-active-jobs", "1"],
            stdout=open(coord_out, "w"), stderr=open(os.path.join(work, "coordinator.err"), "w")))

        def ports():
            text = open(coord_out).read()
            if "dashboard on port" not in text:
                return None
            grpc_port = int(text.split("listening on port ")[1].split()[0])
            return grpc_port, int(text.split("dashboard on port ")[1].split()[0])
        grpc_port, http_port = wait_for("the coordinator's ports", ports, 30)
        site = "http://127.0.0.1:{0}".format(http_port)
        server = "127.0.0.1:{0}".format(grpc_port)

        # HTTP-level auth before any browser: no token, no data; a POST needs the intent header.
        assert http(site + "/api/v1/jobs")[0] == 401
        assert http(site + "/api/v1/jobs", headers={"Authorization": "Bearer wrong"})[0] == 401
        assert http(site + "/api/v1/jobs", headers={"Authorization": "Bearer " + TOKEN})[0] == 200
        assert http(site + "/metrics")[0] == 401

        procs.append(subprocess.Popen(
            [os.path.join(build, "lightfarm-worker"), "--coordinator", server, "--token-file",
             os.path.join(work, "token"), "--threads", "1", "--cache-dir", os.path.join(work, "cache"),
             "--name", "browser-test-worker"],
            stdout=subprocess.DEVNULL, stderr=open(os.path.join(work, "worker.err"), "w")))

        def submit(*args):
            out = subprocess.run([cli, "submit", scene, "--server", server, "--token-file", os.path.join(work, "token")]
                                 + list(args), check=True, capture_output=True, text=True).stdout
            return out.strip().split()[-1]
        # A: progressive, a preview per pass; B: queued behind it (one active job), to cancel.
        job_a = submit("--method", "brute", "--lights", "8000", "--resolution", "96x96", "--passes", "4",
                       "--name", EVIL)
        job_b = submit("--method", "brute", "--lights", "3000", "--resolution", "96x96", "--name", "second job")
        # C: a scene with a syntax error; its page must show where.
        broken = os.path.join(work, "broken.pbrt")
        with open(broken, "w") as f:
            f.write('Film "rgb" "integer xresolution" [16] "integer yresolution" [16]\nCamera "perspective"\n'
                    'WorldBegin\nShape "sphere" "float radius" [ 1\n')
        job_c = subprocess.run([cli, "submit", broken, "--server", server, "--token-file", os.path.join(work, "token"),
                                "--method", "brute", "--priority", "9"], check=True, capture_output=True,
                               text=True).stdout.strip().split()[-1]
        assert http(site + "/api/v1/jobs/" + job_b + "/cancel", method="POST",
                    headers={"Authorization": "Bearer " + TOKEN}, data=b"{}")[0] == 403

        driver_port = free_port()
        procs.append(subprocess.Popen(["chromedriver", "--port={0}".format(driver_port)],
                                      stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        wait_for("chromedriver", lambda: http("http://127.0.0.1:{0}/status".format(driver_port))[0] == 200, 30)
        driver = WebDriver(driver_port)

        # Log in: the page redirects to the form; a wrong token is refused, the right one sets the cookie.
        driver.get(site + "/")
        wait_for("the login page", lambda: driver.url().endswith("/login"))
        driver.type("#token", "wrong")
        driver.click("#login")
        wait_for("the wrong-token message", lambda: "wrong token" in driver.js("return document.body.innerText"))
        driver.type("#token", TOKEN)
        driver.click("#login")
        wait_for("the job list", lambda: driver.js("return document.querySelectorAll('#jobs tbody tr').length") == 3)
        cookie_js = driver.js("return document.cookie")
        assert "lightfarm_session" not in cookie_js, "the session cookie must be HttpOnly"

        # The job list: the <script> name is text, nothing ran.
        name = driver.js("return document.querySelector('tr[data-job-id=\"%s\"] td.name').textContent" % job_a)
        assert name == EVIL, name
        assert driver.js("return window.pwned === undefined && document.querySelectorAll('td.name script, td.name img').length === 0")
        driver.screenshot(os.path.join(shots, "jobs.png"))

        # A's page: a live preview while it renders, then the result, the EXR link and the stats.
        driver.click('a[href="/jobs/%s"]' % job_a)
        wait_for("job A's page", lambda: driver.js("return document.getElementById('job-state') !== null"))
        assert driver.js("return document.getElementById('job-name').textContent") == EVIL
        wait_for("a live preview while job A runs", lambda: driver.js(
            "const s = document.getElementById('job-state').textContent, p = document.getElementById('preview');"
            "return s === 'running' && p !== null && p.complete && p.naturalWidth === 96"), 120, 0.05)
        driver.screenshot(os.path.join(shots, "job-running.png"))
        driver.click("#nav-jobs")
        wait_for("the job list again", lambda: driver.js("return document.querySelectorAll('#jobs tbody tr').length") == 3)

        # B's page: raise its priority (it is queued behind A).
        driver.click('a[href="/jobs/%s"]' % job_b)
        wait_for("job B's page", lambda: driver.js("return document.getElementById('priority-input') !== null"))
        driver.type("#priority-input", "7", clear=True)
        driver.click("#priority-set")
        wait_for("job B at priority 7", lambda: json.loads(http(
            site + "/api/v1/jobs/" + job_b, headers={"Authorization": "Bearer " + TOKEN})[1])["priority"] == 7)
        driver.click("#nav-jobs")
        wait_for("B's priority in the list", lambda: driver.js(
            "return document.querySelector('tr[data-job-id=\"%s\"]').cells[5].textContent" % job_b) == "7")

        # Cancel B from the list.
        driver.click('button.cancel[data-job-id="%s"]' % job_b)
        wait_for("job B cancelled on the page", lambda: driver.js(
            "return document.querySelector('tr[data-job-id=\"%s\"]').dataset.state" % job_b) == "cancelled")
        status, body = http(site + "/api/v1/jobs/" + job_b, headers={"Authorization": "Bearer " + TOKEN})
        assert json.loads(body)["state"] == "cancelled"

        driver.click('a[href="/jobs/%s"]' % job_a)
        wait_for("job A's page again", lambda: driver.js("return document.getElementById('job-state') !== null"))
        wait_for("job A done", lambda: driver.js("return document.getElementById('job-state').textContent") == "done", 300)
        wait_for("the final image", lambda: driver.js(
            "const i = document.getElementById('final-image'); return i !== null && i.complete && i.naturalWidth === 96"))
        stats = driver.js("const r = {}; for (const tr of document.querySelectorAll('#stats tr'))"
                          " r[tr.cells[0].textContent] = tr.cells[1].textContent; return r")
        assert stats.get("method") == "brute" and stats.get("passes") == "4", stats
        href = driver.js("return document.getElementById('download-exr').href")
        status, exr = http(href, headers={"Authorization": "Bearer " + TOKEN})
        assert status == 200 and exr[:4] == b"\x76\x2f\x31\x01", "the EXR link serves an OpenEXR file"
        assert driver.js("return document.getElementById('bench-link') !== null")
        driver.screenshot(os.path.join(shots, "job-done.png"))

        # C's page: failed, with the scene's file:line.
        driver.get(site + "/jobs/" + job_c)
        wait_for("job C failed with its file:line", lambda: "broken.pbrt:4" in driver.js(
            "const e = document.getElementById('job-error'); return e ? e.textContent : ''"))
        assert driver.js("return document.getElementById('job-state').textContent") == "failed"
        driver.screenshot(os.path.join(shots, "job-failed.png"))

        # Priority cannot change on an ended job; the API says why.
        status, body = http(site + "/api/v1/jobs/" + job_a + "/priority", method="POST",
                            headers={"Authorization": "Bearer " + TOKEN, "X-Lightfarm-Request": "1"},
                            data=b'{"priority": 5}')
        assert status == 409, (status, body)

        # Workers: this worker, its tasks.
        driver.click("#nav-workers")
        wait_for("the worker row", lambda: driver.js(
            "const r = document.querySelector('#workers tbody tr'); return r && r.cells[0].textContent === 'browser-test-worker'"
            " && parseInt(r.cells[6].textContent) > 0"))
        driver.screenshot(os.path.join(shots, "workers.png"))

        # Bench: the error-versus-time plot of the bench results, a point per run.
        driver.click("#nav-bench")
        wait_for("the bench plot", lambda: driver.js(
            "const s = document.querySelector('svg[data-scene=\"cornell-box/scene.pbrt\"]'); return s && s.querySelectorAll('circle[fill]').length >= 4"))
        driver.screenshot(os.path.join(shots, "bench.png"))
        print("dashboard test passed; screenshots in", shots)
    except Exception:
        if driver:  # what the browser showed, for the log
            try:
                print("browser at", driver.url(), "showing:\n", driver.js("return document.body.innerText")[:2000])
                driver.screenshot(os.path.join(shots, "failure.png"))
            except Exception as e:
                print("cannot read the browser's page:", e)
        raise
    finally:
        if driver:
            driver.quit()
        for p in reversed(procs):
            p.terminate()
        for p in reversed(procs):
            try:
                p.wait(timeout=15)
            except subprocess.TimeoutExpired:
                p.kill()
        if os.environ.get("LIGHTFARM_KEEP_TEST_DIRS"):
            print("kept", work)
        else:
            shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
