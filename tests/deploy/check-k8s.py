#!/usr/bin/python3
"""Checks deploy/k8s (the kustomize base) without a cluster.

What is checked:
  * every manifest the kustomization lists exists and parses; kinds and API versions are the ones
    the base uses; names are DNS-1123 labels; selectors match their pod templates; ports and
    volumes a container refers to are declared; Service target ports name container ports; the
    StatefulSet's serviceName is a Service; the workers' --coordinator is that Service's port;
  * the probes are gRPC probes on the coordinator's gRPC port, and that port answers
    grpc.health.v1.Health/Check with SERVING without the token (while any other call without it
    is UNAUTHENTICATED): the real coordinator is started with the container's own arguments;
  * the worker Deployment scales: three workers started with the pod's own arguments register
    with distinct ids and share the coordinator (pods of a Deployment are identical copies).
What cannot be checked here (no API server, no image registry, no storage): validation against
the cluster's OpenAPI schemas, image pulls, PersistentVolumeClaim binding, `kubectl scale` itself.

Usage: check-k8s.py BUILD_DIR
"""
import os
import re
import signal
import socket
import subprocess
import sys
import tempfile
import time
import urllib.error
import urllib.request

import grpc
import yaml

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
K8S = os.path.join(ROOT, "deploy", "k8s")
KNOWN = {("v1", "Service"), ("v1", "Secret"), ("apps/v1", "StatefulSet"), ("apps/v1", "Deployment")}
DNS1123 = re.compile(r"^[a-z0-9]([-a-z0-9]*[a-z0-9])?$")
failures = []


def check(ok, message):
    if not ok:
        failures.append(message)
    return ok


def load():
    kustomization = yaml.safe_load(open(os.path.join(K8S, "kustomization.yaml")))
    check(kustomization.get("kind") == "Kustomization", "kustomization.yaml is not a Kustomization")
    docs = []
    for resource in kustomization["resources"]:
        path = os.path.join(K8S, resource)
        if not check(os.path.isfile(path), f"kustomization lists {resource}, which does not exist"):
            continue
        for doc in yaml.safe_load_all(open(path)):
            if doc:
                doc["_file"] = resource
                docs.append(doc)
    return docs


def containers(doc):
    return doc["spec"]["template"]["spec"]["containers"]


def check_structure(docs):
    by_kind = {}
    for d in docs:
        where = f"{d['_file']}: {d.get('kind')} {d.get('metadata', {}).get('name')}"
        check((d.get("apiVersion"), d.get("kind")) in KNOWN, f"{where}: unexpected apiVersion/kind")
        name = d.get("metadata", {}).get("name", "")
        check(bool(DNS1123.match(name)) and len(name) <= 63, f"{where}: name is not a DNS-1123 label")
        by_kind.setdefault(d["kind"], []).append(d)
        if d["kind"] in ("StatefulSet", "Deployment"):
            spec = d["spec"]
            labels = spec["template"]["metadata"]["labels"]
            selector = spec["selector"]["matchLabels"]
            check(all(labels.get(k) == v for k, v in selector.items()), f"{where}: selector does not match the template")
            volumes = {v["name"] for v in spec["template"]["spec"].get("volumes", [])}
            volumes |= {t["metadata"]["name"] for t in spec.get("volumeClaimTemplates", [])}
            for c in containers(d):
                check(bool(c.get("image")), f"{where}: container {c.get('name')} has no image")
                for m in c.get("volumeMounts", []):
                    check(m["name"] in volumes, f"{where}: mount {m['name']} has no volume")
                ports = {p["name"]: p["containerPort"] for p in c.get("ports", [])}
                for p in ports:
                    check(len(p) <= 15 and DNS1123.match(p), f"{where}: port name {p} is not an IANA service name")
                for probe in ("readinessProbe", "livenessProbe"):
                    if probe in c:
                        g = c[probe].get("grpc")
                        check(g is not None, f"{where}: {probe} is not a gRPC probe")
                        if g:
                            check(g["port"] == ports.get("grpc"), f"{where}: {probe} is not on the gRPC port")
    return by_kind


def http_status(url, headers=None):
    req = urllib.request.Request(url, headers=headers or {})
    try:
        with urllib.request.urlopen(req, timeout=10) as r:
            return r.status
    except urllib.error.HTTPError as e:
        return e.code


def free_port():
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


def arg_value(args, flag):
    return args[args.index(flag) + 1]


def replace_arg(args, flag, value):
    out = list(args)
    out[out.index(flag) + 1] = value
    return out


def health(address):
    channel = grpc.insecure_channel(address)
    check_rpc = channel.unary_unary("/grpc.health.v1.Health/Check",
                                    request_serializer=lambda b: b, response_deserializer=lambda b: b)
    try:
        return check_rpc(b"", timeout=5)
    finally:
        channel.close()


def list_jobs_code(address):
    channel = grpc.insecure_channel(address)
    call = channel.unary_unary("/lightfarm.v1.RenderService/ListJobs",
                               request_serializer=lambda b: b, response_deserializer=lambda b: b)
    try:
        call(b"", timeout=5)
        return grpc.StatusCode.OK
    except grpc.RpcError as e:
        return e.code()
    finally:
        channel.close()


def run_pods(build, by_kind, tmp):
    coordinator = by_kind["StatefulSet"][0]
    worker_deploy = by_kind["Deployment"][0]
    service = next(s for s in by_kind["Service"] if s["metadata"]["name"] == coordinator["spec"]["serviceName"])
    c = containers(coordinator)[0]
    w = containers(worker_deploy)[0]
    grpc_port = next(p["containerPort"] for p in c["ports"] if p["name"] == "grpc")
    service_port = next(p["port"] for p in service["spec"]["ports"] if p["targetPort"] == "grpc")
    coordinator_flag = arg_value(w["args"], "--coordinator")
    check(coordinator_flag == f"{service['metadata']['name']}:{service_port}",
          f"workers reach {coordinator_flag}, the Service is {service['metadata']['name']}:{service_port}")
    check(arg_value(c["args"], "--listen").endswith(f":{grpc_port}"), "the coordinator does not listen on its gRPC port")

    # The pods' own arguments, with paths and addresses mapped into this machine.
    token = os.path.join(tmp, "token")
    with open(token, "w") as f:
        f.write("k8s-test-token\n")
    port = free_port()
    address = f"127.0.0.1:{port}"
    args = replace_arg(c["args"], "--listen", address)
    args = replace_arg(args, "--state-dir", os.path.join(tmp, "state"))
    args = replace_arg(args, "--token-file", token)
    args = replace_arg(args, "--metrics-listen", f"127.0.0.1:{free_port()}")
    http_port = free_port()
    check("--http-listen" in args, "the coordinator serves no dashboard (--http-listen)")
    args = replace_arg(args, "--http-listen", f"127.0.0.1:{http_port}")
    procs = []
    log = open(os.path.join(tmp, "coordinator.log"), "w")
    procs.append(subprocess.Popen([os.path.join(build, c["command"][0])] + args, stdout=log, stderr=log))
    try:
        deadline = time.time() + 20
        answer = None
        while time.time() < deadline and answer is None:
            try:
                answer = health(address)
            except grpc.RpcError:
                time.sleep(0.2)
        check(answer == b"\x08\x01", f"the gRPC probe's health check got {answer!r}, not SERVING")
        check(list_jobs_code(address) == grpc.StatusCode.UNAUTHENTICATED,
              "a call without the token was not refused (the probe would pass for the wrong reason)")
        # The dashboard Service port: the pod's token guards it too.
        jobs = f"http://127.0.0.1:{http_port}/api/v1/jobs"
        check(http_status(jobs) == 401, "the dashboard answered without the token")
        check(http_status(jobs, {"Authorization": "Bearer k8s-test-token"}) == 200,
              "the dashboard refused the pod's token")
        worker_logs = []
        for i in range(3):
            wargs = replace_arg(w["args"], "--coordinator", address)
            wargs = replace_arg(wargs, "--token-file", token)
            wargs = replace_arg(wargs, "--cache-dir", os.path.join(tmp, f"cache-{i}"))
            path = os.path.join(tmp, f"worker-{i}.log")
            worker_logs.append(path)
            wlog = open(path, "w")
            procs.append(subprocess.Popen([os.path.join(build, w["command"][0])] + wargs + ["--threads", "1"],
                                          stdout=wlog, stderr=wlog))
        ids = set()
        deadline = time.time() + 20
        while time.time() < deadline and len(ids) < 3:
            ids = set()
            for path in worker_logs:
                m = re.search(r"registered as (\S+)", open(path).read())
                if m:
                    ids.add(m.group(1))
            time.sleep(0.2)
        check(len(ids) == 3, f"3 replicas of the worker pod registered {len(ids)} distinct workers")
    finally:
        for p in reversed(procs):
            p.send_signal(signal.SIGTERM)
        for p in procs:
            try:
                p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                p.kill()


def main():
    build = os.path.abspath(sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "build"))
    docs = load()
    by_kind = check_structure(docs)
    check(len(by_kind.get("StatefulSet", [])) == 1 and len(by_kind.get("Deployment", [])) == 1,
          "expected one coordinator StatefulSet and one worker Deployment")
    if not failures:
        with tempfile.TemporaryDirectory() as tmp:
            run_pods(build, by_kind, tmp)
    for f in failures:
        print("FAIL:", f)
    if failures:
        return 1
    print(f"k8s: {len(docs)} manifests consistent; gRPC health probe SERVING without the token; 3 worker replicas registered")
    return 0


if __name__ == "__main__":
    sys.exit(main())
