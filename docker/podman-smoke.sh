#!/usr/bin/env bash
# Build the real docker/Dockerfile with podman and smoke-test the image on a machine with no
# Docker daemon and no image registry:
#   1. a Debian bookworm root made by debootstrap (cached as localhost/calf-debian:bookworm),
#      and from it stand-ins for python:3.11-slim, postgres and redis (docker/smoke/);
#   2. the image itself from docker/Dockerfile (PYTHON_IMAGE = the stand-in), alone: serve on
#      SQLite, then upload -> job -> record -> every surface export (STL, GLB, glTF, STEP,
#      IGES, 3dm, geomdl) -> a design and its knitting spec;
#   3. docker/compose.yaml with podman-compose (api + worker + PostgreSQL + Redis), waiting on
#      each healthcheck here (podman 4.3 does not run them without systemd), and the same
#      smoke test through the Dramatiq worker.
# Containers, volumes and networks it made are removed on exit; images stay as a cache
# (CALF_SMOKE_CLEAN=1 removes them too).  Skips, saying why, where podman is absent.
#   bash docker/podman-smoke.sh
set -euo pipefail

if ! command -v podman >/dev/null 2>&1; then
  echo "podman-smoke: skipped: podman is not installed (Debian: apt-get install podman podman-compose buildah debootstrap runc)"
  exit 0
fi
for tool in debootstrap podman-compose runc curl python3; do
  if ! command -v "$tool" >/dev/null 2>&1; then
    echo "podman-smoke: skipped: $tool is not installed (Debian: apt-get install podman podman-compose buildah debootstrap runc)"
    exit 0
  fi
done

ROOT="$(cd "$(dirname "$0")/.." && pwd)"
WORK="${CALF_SMOKE_DIR:-/var/tmp/calf-podman}"
MIRROR="${CALF_DEBIAN_MIRROR:-http://deb.debian.org/debian}"
PORT="${CALF_SMOKE_PORT:-18000}"
PROJECT="calfsmoke"
mkdir -p "$WORK"

# runc (crun fails on this kind of machine) and ulimits the container may set: nofile up to
# this shell's hard limit; nproc 4096 (raising it to the hard limit is refused here)
nofile="$(ulimit -Hn)"; [ "$nofile" = unlimited ] && nofile=65536
[ "$nofile" -gt 65536 ] && nofile=65536
cat > "$WORK/containers.conf" <<CONF
[containers]
default_ulimits = ["nofile=$nofile:$nofile", "nproc=4096:4096"]
[engine]
runtime = "runc"
CONF
export CONTAINERS_CONF="$WORK/containers.conf"

step() { printf '\n== %s (%ss)\n' "$*" "$SECONDS"; }
fail() { echo "podman-smoke: FAILED: $*" >&2; exit 1; }

cleanup() {
  set +e
  podman rm -f -t 2 calfsmoke-api >/dev/null 2>&1
  podman volume rm -f calfsmoke-data >/dev/null 2>&1
  (cd "$ROOT/docker" && podman-compose -p "$PROJECT" -f compose.yaml down -v >/dev/null 2>&1)
  podman pod rm -f "pod_$PROJECT" >/dev/null 2>&1
  if [ "${CALF_SMOKE_CLEAN:-0}" = 1 ]; then
    podman rmi -f localhost/calf-nurbs:smoke localhost/calf-python:3.11 localhost/calf-postgres:15 \
      localhost/calf-redis:7 localhost/calf-debian:bookworm >/dev/null 2>&1
  fi
}
trap cleanup EXIT

step "base: Debian bookworm by debootstrap"
if ! podman image exists localhost/calf-debian:bookworm; then
  rm -rf "$WORK/rootfs"
  debootstrap --variant=minbase --include=python3,python3-venv,ca-certificates bookworm "$WORK/rootfs" "$MIRROR" \
    > "$WORK/debootstrap.log" 2>&1 || { tail -20 "$WORK/debootstrap.log"; fail "debootstrap"; }
  tar -C "$WORK/rootfs" -c . | podman import --change 'CMD ["bash"]' - localhost/calf-debian:bookworm >/dev/null
  rm -rf "$WORK/rootfs"
fi
# the stand-ins' build context: docker/smoke and this machine's CA bundle, outside the tree
rm -rf "$WORK/context" && cp -r "$ROOT/docker/smoke" "$WORK/context"
cp /etc/ssl/certs/ca-certificates.crt "$WORK/context/ca-certificates.crt"
for stand_in in python:calf-python:3.11 postgres:calf-postgres:15 redis:calf-redis:7; do
  IFS=: read -r file name tag <<< "$stand_in"
  podman build -q --format docker --network host -f "$WORK/context/Containerfile.$file" -t "localhost/$name:$tag" \
    "$WORK/context" >/dev/null || fail "building the $file stand-in"
done

step "the image, from docker/Dockerfile"
podman build --format docker --network host --build-arg PYTHON_IMAGE=localhost/calf-python:3.11 -f "$ROOT/docker/Dockerfile" \
  -t localhost/calf-nurbs:smoke "$ROOT" > "$WORK/build.log" 2>&1 || { tail -30 "$WORK/build.log"; fail "podman build"; }

wait_healthy() {  # container, seconds: run its healthcheck until it passes
  local name="$1" limit="$2" start=$SECONDS
  until podman healthcheck run "$name" >"$WORK/health.out" 2>&1; do
    if [ "$(podman inspect -f '{{.State.Running}}' "$name" 2>/dev/null)" != true ]; then
      podman logs --tail 30 "$name" >&2 || true
      fail "$name stopped before it was healthy"
    fi
    [ $((SECONDS - start)) -gt "$limit" ] && { podman logs --tail 30 "$name" >&2; cat "$WORK/health.out" >&2; fail "$name not healthy after ${limit}s"; }
    sleep 2
  done
  echo "$name healthy after $((SECONDS - start))s"
}

smoke() {  # base URL, API key: upload -> job -> every export -> a design
  BASE_URL="$1" KEY="$2" SCAN="$ROOT/tests/data/real/bodyparts3d_right_leg.stl" python3 - <<'PY'
import json, os, sys, time, urllib.request, urllib.error

base, key, scan = os.environ["BASE_URL"], os.environ["KEY"], os.environ["SCAN"]

def call(method, path, body=None, content_type=None, accept=None):
    request = urllib.request.Request(base + path, data=body, method=method)
    request.add_header("Authorization", f"Bearer {key}")
    if content_type:
        request.add_header("Content-Type", content_type)
    if accept:
        request.add_header("Accept", accept)
    try:
        with urllib.request.urlopen(request, timeout=120) as answer:
            return answer.status, answer.headers, answer.read()
    except urllib.error.HTTPError as error:
        return error.code, error.headers, error.read()

status, headers, body = call("POST", "/api/v1/scans?side=right", open(scan, "rb").read(), "model/stl")
assert status == 202, (status, body[:400])
job_url = headers["Location"]
for _ in range(300):
    status, _, body = call("GET", job_url)
    job = json.loads(body)
    if job["status"] in ("succeeded", "failed"):
        break
    time.sleep(1)
assert job["status"] == "succeeded", job
record = job["record_id"]
print(f"fit: record {record}")
for fmt, magic in {"stl": b"", "glb": b"glTF", "gltf": b"{", "step": b"ISO-10303-21", "iges": b"", "3dm": b"3D Geometry",
                   "geomdl": b"{"}.items():
    status, headers, body = call("GET", f"/api/v1/records/{record}/surface?format={fmt}")
    assert status == 200 and len(body) > 1000 and body.startswith(magic), (fmt, status, body[:300])
    print(f"export {fmt}: {len(body)} bytes, {headers['Content-Type']}")
status, _, body = call("GET", f"/api/v1/records/{record}/measurements")
assert status == 200, body[:300]
status, headers, body = call("POST", f"/api/v1/records/{record}/designs",
                             json.dumps({"compression_class": "II", "fabric": {"stiffness_n_per_cm": 10}}).encode(),
                             "application/json")
assert status == 201, (status, body[:300])
design = json.loads(body)
status, _, body = call("GET", f"/api/v1/designs/{design['id']}/knitting-spec")
assert status == 200 and b"relaxed_circumference_mm" in body, body[:300]
print(f"design {design['id']}: verdict {design['verdict']}, knitting spec {len(body)} bytes")
PY
}

step "the image alone: SQLite, in-process runner"
podman volume create calfsmoke-data >/dev/null
podman run -d --name calfsmoke-api -p "127.0.0.1:$PORT:8000" -v calfsmoke-data:/data localhost/calf-nurbs:smoke >/dev/null
wait_healthy calfsmoke-api 120
key="$(podman exec calfsmoke-api calf-nurbs keys create --tenant smoke | tail -n 1)"
smoke "http://127.0.0.1:$PORT" "$key"
podman rm -f -t 5 calfsmoke-api >/dev/null

step "compose: api + worker + PostgreSQL + Redis"
cd "$ROOT/docker"
export CALF_PORT="$((PORT + 1))" CALF_IMAGE=localhost/calf-nurbs:smoke CALF_POSTGRES_IMAGE=localhost/calf-postgres:15 CALF_REDIS_IMAGE=localhost/calf-redis:7
compose() { podman-compose -p "$PROJECT" -f compose.yaml "$@"; }
compose up -d --no-build db redis > "$WORK/compose.log" 2>&1 || { tail -30 "$WORK/compose.log"; fail "compose up db redis"; }
wait_healthy "${PROJECT}_db_1" 120
wait_healthy "${PROJECT}_redis_1" 60
compose up -d --no-build api worker >> "$WORK/compose.log" 2>&1 || { tail -30 "$WORK/compose.log"; fail "compose up api worker"; }
wait_healthy "${PROJECT}_api_1" 180
key="$(podman exec "${PROJECT}_api_1" calf-nurbs keys create --tenant smoke | tail -n 1)"
smoke "http://127.0.0.1:$CALF_PORT" "$key"
echo "the worker's last log lines:"; podman logs --tail 3 "${PROJECT}_worker_1" 2>&1 | cut -c1-240
step "podman-smoke: passed"
