#!/usr/bin/env bash
# The GPU measurements in one short run, for a lent NVIDIA machine (its image has JAX with CUDA,
# Python 3.12 and no network): fitness-kernel throughput (benchmarks/throughput.py), the escape
# study's time up to 10,000 restarts (benchmarks/escape_bench.py), the certified search beside
# the sampled one on paper-case-1 (benchmarks/certified_speed.py, 200 restarts: its dense shapely
# oracle runs on the CPU, about 0.2 s per path), scenes at scale (benchmarks/scene_scale.py: 16
# and 1,000 circles, 16 and 250 triangles and the map, each row a fresh process with no
# persistent cache; untested on a GPU so far) and the certified check's tests on the GPU, where
# its bisection runs 1024 lanes when more than 2048 paths need it (4096 on CPU). Each step has
# its own time limit (580 s in all: a device command may run 600; on an H200 at commit 7eae425
# the steps took 2 s and 99 s (throughput at 5 repeats, now 3), the escape step ran out of 100
# s (alone: 104 s), the certified one out of 90 s just after its table, and the tests 213 s)
# and its log in $OUT; a step that fails or runs out of time does not stop the next.
#
#   benchmarks/on_device.sh prepare   # here, first: wheels the image lacks, into .whl/
#   benchmarks/on_device.sh           # there: device tool, carry [".whl"], timeout_s 590
#   QUICK=1 OUT=/tmp/dry PYTHON=.venv/bin/python benchmarks/on_device.sh  # dry run, small sizes
set -uo pipefail
cd "$(dirname "$0")/.."
WHEELS=.whl
if [ "${1:-}" = prepare ]; then
  exec python3 -m pip download --quiet --no-deps --only-binary=:all: --python-version 3.12 \
    --implementation cp --platform manylinux_2_28_x86_64 --platform manylinux_2_17_x86_64 \
    --platform manylinux2014_x86_64 -d "$WHEELS" shapely==2.2.0 tomli-w==1.2.0
fi
OUT="${OUT:?set OUT to the folder for the logs}"
PYTHON="${PYTHON:-python3}"
export PYTHONPATH="$PWD" PYTHONUNBUFFERED=1 JAXARM_CACHE_DIR=off
# The wheels are installed only where their packages are missing (tomli-w for jaxarm itself,
# shapely for the tests' oracle).
if ! "$PYTHON" -c "import shapely, tomli_w" 2>/dev/null; then
  "$PYTHON" -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade \
    --target /tmp/site "$WHEELS"/*.whl || exit
  export PYTHONPATH="/tmp/site:$PWD"
fi
if [ -n "${QUICK:-}" ]; then
  batch=(--max-batch 10000 --certified-max-batch 10000 --numpy-max-batch 10000 --repeats 2)
  restarts=(--repeats 1 --max-restarts 100)
  tests=(tests/test_certified.py -k "sound_and_not_too_conservative")
  certified=(--restarts 16 --repeats 1 --scenarios paper-case-1)
  scale=(--circles 16 --triangles 16 --timeout 50)
else
  batch=(--max-batch 1000000 --certified-max-batch 1000000 --numpy-max-batch 10000
         --repeats 3)
  restarts=(--repeats 3 --max-restarts 10000)
  tests=(tests/test_certified.py)
  certified=(--restarts 200 --repeats 3 --scenarios paper-case-1)
  scale=(--circles 16,1000 --triangles 16,250 --map --timeout 25)
fi
platform=$("$PYTHON" -c "import jax; print('cuda' if jax.default_backend() == 'gpu' else 'cpu')")

step() {  # name, seconds, command...: the command's output into $OUT/name.log and its tail here
  local name=$1 limit=$2 began=$SECONDS
  shift 2
  echo "== $name (limit ${limit} s): $*"
  timeout "$limit" "$@" >"$OUT/$name.log" 2>&1
  local code=$?
  tail -n 30 "$OUT/$name.log"
  echo "== $name: exit $code after $((SECONDS - began)) s" | tee -a "$OUT/steps.log"
}

step devices 20 bash -c "nvidia-smi -L; $PYTHON -c 'import jax, jaxarm; \
print(\"jax\", jax.__version__, jax.devices(), \"jaxarm\", jaxarm.__version__)'"
step throughput 90 "$PYTHON" benchmarks/throughput.py "${batch[@]}"
step escape 115 "$PYTHON" benchmarks/escape_bench.py "${restarts[@]}"
step certified 110 "$PYTHON" benchmarks/certified_speed.py "${certified[@]}"
step scale 110 "$PYTHON" benchmarks/scene_scale.py "${scale[@]}"
step tests 135 env JAX_PLATFORMS="$platform" "$PYTHON" -m pytest -q -p no:cacheprovider \
  "${tests[@]}"
