"""lightfarm: a Python client for the lightfarm render farm.

    import lightfarm
    client = lightfarm.Client("localhost:50051", token=open("token").read().strip())
    job = client.submit("scenes/cornell-box/scene.pbrt", method="brute", lights=10000, resolution=(256, 256))
    for status in job.watch():
        print(status.state, status.tasks_done, "/", status.tasks_total)
    image, stats = job.result()   # float32 array (height, width, channels), stats dict
"""

__version__ = "0.1.0"

from .client import Client, Job, JobStatus, Result, WorkerStatus  # noqa: F401
from .errors import JobCancelled, JobFailed, LightfarmError  # noqa: F401
from .scene import scene_files  # noqa: F401
