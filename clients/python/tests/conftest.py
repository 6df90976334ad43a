"""A real farm for the client's tests: a coordinator with a token on loopback and one worker,
from the build directory ($LIGHTFARM_BUILD_DIR)."""

import os
import subprocess
import time

import pytest

TOKEN = "python-client-test-token"


def _build_dir():
    build = os.environ.get("LIGHTFARM_BUILD_DIR")
    if not build or not os.path.isfile(os.path.join(build, "lightfarm-coordinator")):
        pytest.fail("set LIGHTFARM_BUILD_DIR to a build directory with lightfarm-coordinator (clients/python/tests/run.sh does)")
    return build


@pytest.fixture(scope="session")
def source_dir():
    return os.environ.get("LIGHTFARM_SOURCE_DIR") or os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..", ".."))


@pytest.fixture(scope="session")
def build_dir():
    return _build_dir()


@pytest.fixture(scope="session")
def farm(tmp_path_factory, build_dir):
    work = tmp_path_factory.mktemp("farm")
    token_file = work / "token"
    token_file.write_text(TOKEN + "\n")
    out = work / "coordinator.out"
    coordinator = subprocess.Popen(
        [os.path.join(build_dir, "lightfarm-coordinator"), "--listen", "127.0.0.1:0", "--state-dir", str(work / "state"),
         "--token-file", str(token_file)],
        stdout=open(out, "w"), stderr=open(work / "coordinator.err", "w"))
    deadline = time.time() + 30
    while "listening on port" not in out.read_text():
        if time.time() > deadline or coordinator.poll() is not None:
            coordinator.kill()
            pytest.fail("the coordinator did not start: " + (work / "coordinator.err").read_text())
        time.sleep(0.05)
    port = int(out.read_text().split("listening on port ")[1].split()[0])
    address = "127.0.0.1:{0}".format(port)
    worker = subprocess.Popen(
        [os.path.join(build_dir, "lightfarm-worker"), "--coordinator", address, "--token-file", str(token_file),
         "--threads", "2", "--cache-dir", str(work / "cache"), "--name", "pytest-worker"],
        stdout=subprocess.DEVNULL, stderr=open(work / "worker.err", "w"))
    yield {"address": address, "token": TOKEN, "token_file": str(token_file), "work": work}
    for p in (worker, coordinator):
        p.terminate()
    for p in (worker, coordinator):
        try:
            p.wait(timeout=15)
        except subprocess.TimeoutExpired:
            p.kill()
