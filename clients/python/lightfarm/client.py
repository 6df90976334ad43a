"""A Pythonic API over lightfarm's gRPC RenderService (proto/lightfarm/v1/render.proto)."""

import dataclasses
import hashlib
import json
import os
import tempfile
import time

import grpc

from .errors import JobCancelled, JobFailed, LightfarmError
from .scene import scene_files
from .v1 import render_pb2, render_pb2_grpc, types_pb2

CHUNK_BYTES = 1 << 20  # the farm's chunk size (farm_protocol.h kChunkBytes)
_STATES = {types_pb2.JOB_STATE_QUEUED: "queued", types_pb2.JOB_STATE_PLANNING: "planning",
           types_pb2.JOB_STATE_RUNNING: "running", types_pb2.JOB_STATE_DONE: "done",
           types_pb2.JOB_STATE_FAILED: "failed", types_pb2.JOB_STATE_CANCELLED: "cancelled"}
TERMINAL = {"done", "failed", "cancelled"}


@dataclasses.dataclass(frozen=True)
class JobStatus:
    """A job's state and progress (JobStatus in render.proto); `state` is "queued" ... "cancelled"."""
    job_id: str
    state: str
    name: str
    scene: str
    method: str
    priority: int
    stage: int
    stage_count: int
    stage_name: str
    tasks_done: int
    tasks_total: int
    elapsed_s: float
    eta_s: float
    error: str
    attempts: int
    progressive: bool
    passes_done: int
    passes_total: int
    noise_rel_stderr: float
    preview_png: bytes = b""

    @property
    def finished(self):
        return self.state in TERMINAL

    @classmethod
    def from_proto(cls, m):
        return cls(job_id=m.job_id, state=_STATES.get(m.state, "unknown"), name=m.name, scene=m.scene,
                   method=m.method, priority=m.priority, stage=m.stage, stage_count=m.stage_count,
                   stage_name=m.stage_name, tasks_done=m.tasks_done, tasks_total=m.tasks_total,
                   elapsed_s=m.elapsed_s, eta_s=m.eta_s, error=m.error, attempts=m.attempts,
                   progressive=m.progressive, passes_done=m.passes_done, passes_total=m.passes_total,
                   noise_rel_stderr=m.noise_rel_stderr, preview_png=bytes(m.preview_png))


@dataclasses.dataclass(frozen=True)
class WorkerStatus:
    worker_id: str
    name: str
    version: str
    threads: int
    job_id: str
    last_seen_s: float
    alive: bool
    tasks_done: int
    tasks_failed: int
    blocked_jobs: tuple


@dataclasses.dataclass(frozen=True)
class Result:
    """A finished job: `image` (float32, height x width x channels, linear radiance), `stats`
    (the stats JSON as a dict) and `exr` (the EXR file's bytes, as `lightfarm fetch` writes)."""
    image: object
    stats: dict
    exr: bytes

    def __iter__(self):  # image, stats = job.result()
        return iter((self.image, self.stats))


def decode_exr(data):
    """EXR bytes to a float32 NumPy array (height, width, channels), with OpenImageIO."""
    try:
        import OpenImageIO as oiio
    except ImportError as e:
        raise ImportError("reading the result image needs OpenImageIO's Python module "
                          "(Debian: python3-openimageio)") from e
    with tempfile.NamedTemporaryFile(suffix=".exr") as f:
        f.write(data)
        f.flush()
        inp = oiio.ImageInput.open(f.name)
        if inp is None:
            raise ValueError("cannot read the result EXR: " + oiio.geterror())
        try:
            pixels = inp.read_image(0, 0, 0, inp.spec().nchannels, "float")
        finally:
            inp.close()
    if pixels is None:
        raise ValueError("cannot decode the result EXR")
    return pixels


class Job:
    """A submitted job: status, watch, wait, result, cancel."""

    def __init__(self, client, job_id):
        self._client = client
        self.id = job_id

    def __repr__(self):
        return "Job({0!r})".format(self.id)

    def status(self):
        return JobStatus.from_proto(self._client._call("GetJob", render_pb2.GetJobRequest(job_id=self.id)))

    def watch(self, preview=False, preview_interval_s=2.0, timeout=None):
        """Yields the job's status whenever it changes, until it ends (the last one is final).
        With preview=True, statuses carry a PNG of the finished tiles in `preview_png`."""
        req = render_pb2.GetJobRequest(job_id=self.id, preview=preview, preview_interval_s=preview_interval_s)
        try:
            for m in self._client._stub.WatchJob(req, metadata=self._client._metadata, timeout=timeout):
                yield JobStatus.from_proto(m)
        except grpc.RpcError as e:
            if e.code() == grpc.StatusCode.DEADLINE_EXCEEDED:
                raise TimeoutError("job {0} did not end within {1} s".format(self.id, timeout)) from None
            raise LightfarmError.from_rpc(e) from None

    def wait(self, timeout=None):
        """Blocks until the job ends; returns its final status. Raises JobFailed (with the job's
        error: which task, file:line and why), JobCancelled, or TimeoutError."""
        last = None
        for last in self.watch(timeout=timeout):
            pass
        if last is None or not last.finished:
            last = self.status()
        if last.state == "failed":
            raise JobFailed(self.id, last.error)
        if last.state == "cancelled":
            raise JobCancelled(self.id)
        if not last.finished:
            raise TimeoutError("job {0} is still {1}".format(self.id, last.state))
        return last

    def result(self):
        """The finished job's image and stats (a progressive job's mean so far while it runs)."""
        stats, sha, chunks = None, "", []
        try:
            for chunk in self._client._stub.FetchResult(render_pb2.GetJobRequest(job_id=self.id),
                                                        metadata=self._client._metadata,
                                                        timeout=self._client.timeout):
                if stats is None:
                    stats, sha = chunk.stats_json, chunk.exr_sha256
                chunks.append(chunk.exr_data)
        except grpc.RpcError as e:
            raise LightfarmError.from_rpc(e) from None
        exr = b"".join(chunks)
        if sha and hashlib.sha256(exr).hexdigest() != sha:
            raise LightfarmError(grpc.StatusCode.DATA_LOSS,
                                 "the result of job {0} arrived corrupted".format(self.id))
        return Result(image=decode_exr(exr), stats=json.loads(stats or "{}"), exr=exr)

    def cancel(self):
        return JobStatus.from_proto(self._client._call("CancelJob", render_pb2.GetJobRequest(job_id=self.id)))

    def delete(self):
        """Forgets the job on the farm (cancelled first when unfinished): its result, stats and stored work."""
        self._client._call("DeleteJob", render_pb2.GetJobRequest(job_id=self.id))

    def set_priority(self, priority):
        return JobStatus.from_proto(self._client._call(
            "SetJobPriority", render_pb2.SetJobPriorityRequest(job_id=self.id, priority=int(priority))))


class Client:
    """A connection to a lightfarm coordinator.

    address: "host:port". token: the bearer token (the coordinator's --token-file contents).
    tls_ca: a PEM file of the CA that signed the coordinator's certificate (TLS on when given).
    timeout: seconds per unary call and per blob upload."""

    def __init__(self, address, token=None, tls_ca=None, timeout=60.0):
        options = [("grpc.max_receive_message_length", 64 << 20), ("grpc.max_send_message_length", 64 << 20)]
        if tls_ca:
            with open(tls_ca, "rb") as f:
                creds = grpc.ssl_channel_credentials(root_certificates=f.read())
            self._channel = grpc.secure_channel(address, creds, options=options)
        else:
            self._channel = grpc.insecure_channel(address, options=options)
        self._stub = render_pb2_grpc.RenderServiceStub(self._channel)
        self._metadata = [("authorization", "Bearer " + token.strip())] if token else []
        self.address = address
        self.timeout = timeout

    def close(self):
        self._channel.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def _call(self, method, request):
        try:
            return getattr(self._stub, method)(request, metadata=self._metadata, timeout=self.timeout)
        except grpc.RpcError as e:
            raise LightfarmError.from_rpc(e) from None

    # --- scenes --------------------------------------------------------------------------------------

    def upload_scene(self, scene_path):
        """Uploads the blobs of `scene_path`'s files that the coordinator lacks (by SHA-256, in
        chunks); returns the SceneManifest naming them relative to their common directory."""
        if not os.path.isfile(scene_path):
            raise FileNotFoundError("no scene file " + scene_path)
        files = scene_files(scene_path)
        base = os.path.commonpath([os.path.dirname(f) for f in files])
        manifest = types_pb2.SceneManifest(root=os.path.relpath(files[0], base).replace(os.sep, "/"))
        path_of = {}
        for f in files:
            digest = hashlib.sha256()
            with open(f, "rb") as fh:
                for block in iter(lambda: fh.read(CHUNK_BYTES), b""):
                    digest.update(block)
            sha = digest.hexdigest()
            manifest.files.add(path=os.path.relpath(f, base).replace(os.sep, "/"), sha256=sha)
            path_of[sha] = f
        missing = self._call("FindMissingBlobs", render_pb2.FindMissingBlobsRequest(sha256=list(path_of)))
        for sha in missing.missing:
            self._upload_blob(path_of[sha], sha)
        return manifest

    def _upload_blob(self, path, sha):
        size = os.path.getsize(path)

        def chunks():
            with open(path, "rb") as f:
                first = True
                while True:
                    data = f.read(CHUNK_BYTES)
                    if not data and not first:
                        return
                    yield types_pb2.BlobChunk(sha256=sha if first else "", total_size=size if first else 0, data=data)
                    first = False

        try:
            self._stub.UploadBlob(chunks(), metadata=self._metadata, timeout=self.timeout)
        except grpc.RpcError as e:
            raise LightfarmError.from_rpc(e) from None

    # --- jobs ----------------------------------------------------------------------------------------

    def submit(self, scene_path, method="auto", lights=10000, resolution=None, spp=0, seed=0, params=None,
               name="", priority=0, filter=None, passes=0, until_noise=0.0, time_limit_s=0.0):
        """Uploads the scene's missing blobs and submits a job; returns its Job.

        resolution: (width, height), or None for the scene's Film. params: {"KEY": value} as
        `--param KEY=VALUE`. passes / until_noise / time_limit_s: a progressive job."""
        manifest = self.upload_scene(scene_path)
        width, height = resolution if resolution else (0, 0)
        settings = types_pb2.RenderSettings(
            method=method, width=int(width), height=int(height), filter=filter or "", spp=int(spp),
            lights=int(lights), seed=int(seed),
            params=["{0}={1}".format(k, v) for k, v in (params or {}).items()],
            passes=int(passes), until_noise=float(until_noise), time_limit_s=float(time_limit_s))
        request = render_pb2.SubmitJobRequest(scene=manifest, settings=settings, priority=int(priority),
                                              name=name or os.path.basename(scene_path))
        return Job(self, self._call("SubmitJob", request).job_id)

    def job(self, job_id):
        return Job(self, str(job_id))

    def list_jobs(self):
        return [JobStatus.from_proto(m) for m in self._call("ListJobs", render_pb2.ListJobsRequest()).jobs]

    def list_workers(self):
        return [WorkerStatus(worker_id=w.worker_id, name=w.name, version=w.version, threads=w.threads,
                             job_id=w.job_id, last_seen_s=w.last_seen_s, alive=w.alive, tasks_done=w.tasks_done,
                             tasks_failed=w.tasks_failed, blocked_jobs=tuple(w.blocked_jobs))
                for w in self._call("ListWorkers", render_pb2.ListWorkersRequest()).workers]
