"""A PEP 517 build backend for the lightfarm client that needs only the standard library.

The package's gRPC modules (lightfarm/v1/*_pb2*.py) are generated at build time from the
project's protos, never committed: with `protoc` and `grpc_python_plugin` (Debian's
protobuf-compiler and protobuf-compiler-grpc), or with `python -m grpc_tools.protoc`. The protos
are found in $LIGHTFARM_PROTO_DIR, ../../proto (building from the repository) or ./proto (an
sdist).
"""

import base64
import hashlib
import os
import shutil
import subprocess
import sys
import tarfile
import tempfile
import zipfile
from pathlib import Path

HERE = Path(__file__).resolve().parent.parent  # clients/python
NAME = "lightfarm"
PROTOS = ["types", "render", "worker"]


def _version():
    for line in (HERE / NAME / "__init__.py").read_text().splitlines():
        if line.startswith("__version__"):
            return line.split("=", 1)[1].strip().strip("\"'")
    raise RuntimeError("lightfarm/__init__.py has no __version__")


def _proto_dir():
    candidates = [os.environ.get("LIGHTFARM_PROTO_DIR"), HERE.parent.parent / "proto", HERE / "proto"]
    for c in candidates:
        if c and (Path(c) / "lightfarm" / "v1" / "render.proto").is_file():
            return Path(c)
    raise RuntimeError("cannot find the lightfarm protos (lightfarm/v1/render.proto) in "
                       + ", ".join(str(c) for c in candidates if c) + "; set LIGHTFARM_PROTO_DIR")


def _generate(out_dir):
    """Writes lightfarm/v1/{name}_pb2.py and {name}_pb2_grpc.py under out_dir."""
    proto_dir = _proto_dir()
    sources = [str(proto_dir / "lightfarm" / "v1" / (p + ".proto")) for p in PROTOS]
    protoc, plugin = shutil.which("protoc"), shutil.which("grpc_python_plugin")
    if protoc and plugin:
        cmd = [protoc, "-I", str(proto_dir), "--python_out=" + str(out_dir), "--grpc_python_out=" + str(out_dir),
               "--plugin=protoc-gen-grpc_python=" + plugin] + sources
    else:
        cmd = [sys.executable, "-m", "grpc_tools.protoc", "-I", str(proto_dir), "--python_out=" + str(out_dir),
               "--grpc_python_out=" + str(out_dir)] + sources
    try:
        subprocess.run(cmd, check=True)
    except (OSError, subprocess.CalledProcessError) as e:
        raise RuntimeError("generating the gRPC modules failed (" + " ".join(cmd) + "): " + str(e) +
                           "; install protobuf-compiler and protobuf-compiler-grpc (or python3-grpc-tools)")
    for pkg in [out_dir / NAME, out_dir / NAME / "v1"]:
        init = pkg / "__init__.py"
        if not init.exists():
            init.write_text("")


def _files():
    """(path inside the wheel, bytes) of every file the package installs."""
    out = []
    for path in sorted((HERE / NAME).rglob("*.py")):
        rel = path.relative_to(HERE).as_posix()
        if "/v1/" in rel and rel.endswith(("_pb2.py", "_pb2_grpc.py")):
            continue  # stale generated files are never shipped; they are made below
        out.append((rel, path.read_bytes()))
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        (tmp / NAME / "v1").mkdir(parents=True)
        _generate(tmp)
        for path in sorted((tmp / NAME / "v1").glob("*_pb2*.py")):
            out.append((path.relative_to(tmp).as_posix(), path.read_bytes()))
    return out


def _metadata():
    return ("Metadata-Version: 2.1\nName: {0}\nVersion: {1}\nSummary: Python client for the lightfarm render farm\n"
            "Requires-Python: >=3.9\nRequires-Dist: grpcio\nRequires-Dist: protobuf\nRequires-Dist: numpy\n"
            ).format(NAME, _version())


def _dist_info(files):
    dist = "{0}-{1}.dist-info".format(NAME, _version())
    info = {
        dist + "/METADATA": _metadata().encode(),
        dist + "/WHEEL": b"Wheel-Version: 1.0\nGenerator: lightfarm_build\nRoot-Is-Purelib: true\nTag: py3-none-any\n",
        dist + "/top_level.txt": (NAME + "\n").encode(),
    }
    record = []
    for name, data in list(files) + list(info.items()):
        digest = base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=").decode()
        record.append("{0},sha256={1},{2}".format(name, digest, len(data)))
    record.append(dist + "/RECORD,,")
    info[dist + "/RECORD"] = ("\n".join(record) + "\n").encode()
    return dist, info


# --- PEP 517 hooks ------------------------------------------------------------------------------------

def get_requires_for_build_wheel(config_settings=None):
    return []


def get_requires_for_build_sdist(config_settings=None):
    return []


def prepare_metadata_for_build_wheel(metadata_directory, config_settings=None):
    dist, info = _dist_info([])
    target = Path(metadata_directory) / dist
    target.mkdir(parents=True, exist_ok=True)
    for name in ("METADATA", "WHEEL", "top_level.txt"):
        (target / name).write_bytes(info[dist + "/" + name])
    return dist


def build_wheel(wheel_directory, config_settings=None, metadata_directory=None):
    files = _files()
    dist, info = _dist_info(files)
    wheel = "{0}-{1}-py3-none-any.whl".format(NAME, _version())
    with zipfile.ZipFile(Path(wheel_directory) / wheel, "w", zipfile.ZIP_DEFLATED) as z:
        for name, data in files + list(info.items()):
            z.writestr(zipfile.ZipInfo(name, date_time=(2020, 1, 1, 0, 0, 0)), data)
    return wheel


def build_sdist(sdist_directory, config_settings=None):
    base = "{0}-{1}".format(NAME, _version())
    sdist = base + ".tar.gz"
    with tarfile.open(Path(sdist_directory) / sdist, "w:gz") as tar:
        for rel in ["pyproject.toml", "README.md", "build_backend/lightfarm_build.py"]:
            if (HERE / rel).exists():
                tar.add(HERE / rel, arcname=base + "/" + rel)
        for path in sorted((HERE / NAME).rglob("*.py")):
            tar.add(path, arcname=base + "/" + path.relative_to(HERE).as_posix())
        proto_dir = _proto_dir()
        for p in PROTOS:  # the sdist carries the protos it is generated from
            tar.add(proto_dir / "lightfarm" / "v1" / (p + ".proto"), arcname=base + "/proto/lightfarm/v1/" + p + ".proto")
        info = tarfile.TarInfo(base + "/PKG-INFO")
        data = _metadata().encode()
        info.size = len(data)
        import io
        tar.addfile(info, io.BytesIO(data))
    return sdist
