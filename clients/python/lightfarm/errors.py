"""Exceptions of the lightfarm client: each carries the gRPC status code and message."""

import grpc


class LightfarmError(Exception):
    """A call the coordinator refused or could not answer: `code` (grpc.StatusCode), `message`."""

    def __init__(self, code, message):
        super().__init__("{0}: {1}".format(code.name if isinstance(code, grpc.StatusCode) else code, message))
        self.code = code
        self.message = message

    @classmethod
    def from_rpc(cls, error):
        return cls(error.code(), error.details() or "")


class JobFailed(LightfarmError):
    """The job ended FAILED; `message` is its error (which task, file:line and why)."""

    def __init__(self, job_id, message):
        super().__init__(grpc.StatusCode.ABORTED, message)
        self.job_id = job_id


class JobCancelled(LightfarmError):
    def __init__(self, job_id):
        super().__init__(grpc.StatusCode.CANCELLED, "job {0} was cancelled".format(job_id))
        self.job_id = job_id
