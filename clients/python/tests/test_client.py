"""The lightfarm Python client against a real coordinator and worker."""

import os
import subprocess

import grpc
import numpy as np
import pytest

import lightfarm


@pytest.fixture
def client(farm):
    with lightfarm.Client(farm["address"], token=farm["token"]) as c:
        yield c


@pytest.fixture
def cornell(source_dir):
    return os.path.join(source_dir, "scenes", "cornell-box", "scene.pbrt")


def test_submit_watch_and_result_equal_lightfarm_render_bit_for_bit(client, cornell, build_dir, tmp_path):
    job = client.submit(cornell, method="brute", lights=2000, resolution=(48, 40), seed=11, name="pytest brute")
    statuses = list(job.watch())
    assert statuses, "watch yields the job's statuses"
    assert statuses[-1].state == "done", statuses[-1]
    assert all(not s.finished for s in statuses[:-1])
    assert job.wait(timeout=60).state == "done"
    image, stats = job.result()
    assert image.dtype == np.float32 and image.shape[:2] == (40, 48)
    assert stats["method"] == "brute" and stats["lights"]["vpl"] > 0

    out = tmp_path / "cli.exr"
    subprocess.run([os.path.join(build_dir, "lightfarm"), "render", cornell, "--method", "brute", "--lights", "2000",
                    "--resolution", "48x40", "--seed", "11", "--out", str(out), "--quiet"], check=True)
    expected = lightfarm.client.decode_exr(out.read_bytes())
    assert expected.shape == image.shape
    assert np.array_equal(expected.view(np.uint32), image.view(np.uint32)), \
        "farm result and `lightfarm render` differ in {0} values".format(int(np.sum(expected != image)))


def test_list_jobs_and_workers(client, cornell):
    job = client.submit(cornell, method="brute", lights=200, resolution=(16, 16), name="listed")
    job.wait(timeout=60)
    listed = {s.job_id: s for s in client.list_jobs()}
    assert listed[job.id].name == "listed" and listed[job.id].scene == "scene.pbrt"
    workers = client.list_workers()
    assert any(w.name == "pytest-worker" and w.alive and w.tasks_done > 0 and w.threads == 2 for w in workers), workers


def test_only_missing_blobs_are_uploaded(client, tmp_path, cornell):
    # A scene with a PLY mesh beside it: the manifest names both, relative to their directory.
    scene_dir = tmp_path / "scene"
    (scene_dir / "meshes").mkdir(parents=True)
    text = open(cornell).read()
    (scene_dir / "scene.pbrt").write_text(text + '\nInclude "extra.pbrt"\n')
    (scene_dir / "extra.pbrt").write_text('# nothing but a comment "string filename" "meshes/none.ply"\n'
                                         'AttributeBegin\nShape "plymesh" "string filename" [ "meshes/tri.ply" ]\nAttributeEnd\n')
    (scene_dir / "meshes" / "tri.ply").write_text(
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
        "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n0.1 0 0\n0 0.1 0\n3 0 1 2\n")
    files = lightfarm.scene_files(str(scene_dir / "scene.pbrt"))
    assert [os.path.relpath(f, scene_dir) for f in files] == ["scene.pbrt", "extra.pbrt", os.path.join("meshes", "tri.ply")]
    manifest = client.upload_scene(str(scene_dir / "scene.pbrt"))
    assert manifest.root == "scene.pbrt"
    assert sorted(f.path for f in manifest.files) == ["extra.pbrt", "meshes/tri.ply", "scene.pbrt"]
    # Everything is on the coordinator now: a second upload sends nothing.
    missing = client._call("FindMissingBlobs", lightfarm.client.render_pb2.FindMissingBlobsRequest(
        sha256=[f.sha256 for f in manifest.files])).missing
    assert list(missing) == []
    job = client.submit(str(scene_dir / "scene.pbrt"), method="brute", lights=200, resolution=(16, 16))
    assert job.wait(timeout=60).state == "done"


def test_a_bad_scene_raises_with_its_file_and_line(client, tmp_path):
    bad = tmp_path / "broken.pbrt"
    bad.write_text('Film "rgb" "integer xresolution" [16] "integer yresolution" [16]\n'
                   'Camera "perspective"\nWorldBegin\n'
                   'Shape "sphere" "float radius" [ 1\n')
    job = client.submit(str(bad), method="brute", lights=100)
    with pytest.raises(lightfarm.JobFailed) as failed:
        job.wait(timeout=60)
    assert "broken.pbrt:4" in failed.value.message, failed.value.message
    assert failed.value.job_id == job.id
    # The temporary directory the coordinator materialized the scene in is never named.
    assert "/jobs/" not in failed.value.message and "state" not in failed.value.message


def test_a_wrong_token_raises_unauthenticated(farm, cornell):
    with lightfarm.Client(farm["address"], token="not-the-token") as c:
        with pytest.raises(lightfarm.LightfarmError) as err:
            c.list_jobs()
        assert err.value.code == grpc.StatusCode.UNAUTHENTICATED
        with pytest.raises(lightfarm.LightfarmError) as err:
            c.submit(cornell, method="brute")
        assert err.value.code == grpc.StatusCode.UNAUTHENTICATED
    with lightfarm.Client(farm["address"]) as c:
        with pytest.raises(lightfarm.LightfarmError) as err:
            c.list_jobs()
        assert err.value.code == grpc.StatusCode.UNAUTHENTICATED


def test_errors_carry_the_grpc_status(client):
    with pytest.raises(lightfarm.LightfarmError) as err:
        client.job("999999").status()
    assert err.value.code == grpc.StatusCode.NOT_FOUND and "999999" in err.value.message
    with pytest.raises(FileNotFoundError):
        client.submit("/nonexistent/scene.pbrt")


def test_cancel_and_priority(client, cornell):
    # Long enough to still be running when cancelled (the farm has one worker).
    job = client.submit(cornell, method="brute", lights=20000, resolution=(256, 256), priority=1)
    assert job.set_priority(3).priority == 3
    assert job.cancel().state == "cancelled"
    with pytest.raises(lightfarm.JobCancelled):
        job.wait(timeout=30)
    with pytest.raises(lightfarm.LightfarmError) as err:
        job.set_priority(4)
    assert err.value.code == grpc.StatusCode.FAILED_PRECONDITION
    job.delete()
    with pytest.raises(lightfarm.LightfarmError) as err:
        job.status()
    assert err.value.code == grpc.StatusCode.NOT_FOUND


def test_progressive_job_watch_reports_passes(client, cornell):
    job = client.submit(cornell, method="brute", lights=500, resolution=(24, 24), passes=3)
    last = job.wait(timeout=120)
    assert last.progressive and last.passes_done == 3 and last.passes_total == 3
    image, stats = job.result()
    assert stats["passes"] == 3 and np.all(np.isfinite(image))


def test_the_contact_sheet_example_renders_every_method(farm, cornell, source_dir, tmp_path):
    import OpenImageIO as oiio
    example = os.path.join(source_dir, "clients", "python", "examples", "contact_sheet.py")
    out = tmp_path / "sheet.png"
    import sys
    subprocess.run([sys.executable, example, cornell, "--server", farm["address"], "--token-file", farm["token_file"],
                    "--out", str(out), "--lights", "300", "--resolution", "24x24"], check=True, timeout=600)
    table = (tmp_path / "sheet.md").read_text()
    for method in ["brute", "mrcs", "lightcuts", "lightslice", "sparse-completion", "adaptive-completion", "path", "auto"]:
        assert "| " + method in table, table
    assert "failed" not in table, table
    assert "| brute | " in table and "| 0.0000 |" in table.split("| brute |")[1].split("\n")[0]
    spec = oiio.ImageInput.open(str(out)).spec()
    assert (spec.width, spec.height) == (4 * 192, 2 * (192 + 50))  # 24 px tiles shown 8x


def test_tls_with_a_private_ca(build_dir, tmp_path, cornell):
    # A self-signed certificate for 127.0.0.1 is its own CA.
    key, cert = tmp_path / "key.pem", tmp_path / "cert.pem"
    subprocess.run(["openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-days", "1", "-subj", "/CN=127.0.0.1",
                    "-addext", "subjectAltName=IP:127.0.0.1", "-keyout", str(key), "-out", str(cert)],
                   check=True, capture_output=True)
    out = tmp_path / "coordinator.out"
    coordinator = subprocess.Popen(
        [os.path.join(build_dir, "lightfarm-coordinator"), "--listen", "127.0.0.1:0", "--state-dir", str(tmp_path / "state"),
         "--tls-cert", str(cert), "--tls-key", str(key)], stdout=open(out, "w"), stderr=subprocess.DEVNULL)
    try:
        import time
        deadline = time.time() + 30
        while "listening on port" not in out.read_text() and time.time() < deadline:
            time.sleep(0.05)
        address = "127.0.0.1:" + out.read_text().split("listening on port ")[1].split()[0]
        with lightfarm.Client(address, tls_ca=str(cert)) as c:
            job = c.submit(cornell, method="brute", lights=100, resolution=(8, 8))
            assert [s.job_id for s in c.list_jobs()] == [job.id]
        with lightfarm.Client(address, timeout=5) as plain:
            with pytest.raises(lightfarm.LightfarmError) as err:
                plain.list_jobs()
            assert err.value.code == grpc.StatusCode.UNAVAILABLE
    finally:
        coordinator.terminate()
        coordinator.wait(timeout=15)
