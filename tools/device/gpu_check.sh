#!/usr/bin/env bash
# Issue 19's GPU check, on the device machine, from the repository root (docs/gpu.md):
#   python3 tools/device/prepare.py          # here: the wheels into .whl/ (ignored; carried)
#   bash tools/device/gpu_check.sh           # there, with `.whl` in carry; results under $OUT
# It installs the wheels (no index there) and, from a directory outside the checkout:
#   1. runs the main job twice (`edgetruth run`, the quick study) on VARIANT: cold, then with warm caches;
#   2. checks the two runs' renders are byte-identical (every file hash of every manifest) and their
#      ranging rows equal but for time_s; 2b. re-evaluates the second run's renders twice as it runs and twice with
#      OpenCV on one thread, and compares the calibrations and ranging rows;
#   3. runs the full study (`run --study full --skip-synthetic`) in the time left; a run cut short
#      records how many images were complete;
#   4. where time is left, runs the full study again and compares its renders with the first (FULL_TWICE=0: not);
#   5. where time is left, runs the render bench (`edgetruth bench --only render`: R, the GPU's samples/s).
# Env: VARIANT (cuda_ad_rgb), BUDGET_S (whole script, 480), J (workers, the cores), FULL_ARGS (extra
# options for the full study, e.g. "--limit 2" for a dry run), SITE (where the wheels go), EVAL_REPEAT (1: step 2b),
# FULL (1: steps 3-4), FULL_TWICE (1: step 4), BENCH (1: step 5).
set -u
export PYTHONUNBUFFERED=1
VARIANT=${VARIANT:-cuda_ad_rgb}
BUDGET_S=${BUDGET_S:-480}
J=${J:-$(nproc)}
FULL_ARGS=${FULL_ARGS:-}
SITE=${SITE:-/tmp/edgetruth-site}
OUT=${OUT:-$(mktemp -d)}
REPO=$(pwd)
start=$(date +%s)
left() { echo $(( BUDGET_S - ($(date +%s) - start) )); }
exec > >(tee -a "$OUT/gpu_check.log") 2>&1

ls "$REPO"/.whl/*.whl >/dev/null 2>&1 || { echo "gpu_check: no wheels in .whl/: run python3 tools/device/prepare.py here and carry .whl" >&2; exit 2; }
python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target "$SITE" "$REPO"/.whl/*.whl || exit 2
export PYTHONPATH=$SITE PATH=$SITE/bin:$PATH
WORK=$(mktemp -d); cd "$WORK"   # the installed wheel, not the checkout's folders, is what runs

echo "== environment"
nvidia-smi -L 2>/dev/null || echo "nvidia-smi: none"
python3 - <<'PY'
import importlib, sys
print("python", sys.version.split()[0])
for m in ("edgetruth", "mitsuba", "drjit", "numba", "numpy", "scipy", "cv2", "OpenEXR"):
    mod = importlib.import_module(m)
    print(f"  {m} {getattr(mod, '__version__', '?')} {mod.__file__}")
PY
python3 -c "from edgetruth.render import variants; ok, why = variants.probe_uncached('$VARIANT'); print('probe $VARIANT:', 'ok' if ok else why); raise SystemExit(0 if ok else 3)" || exit 3

progress() {  # progress RUN_DIR: how many of the run's images are complete
python3 - "$1" <<'PY' | tee -a "$OUT/full_progress.txt"
import json, sys
from pathlib import Path
done = total = 0
for man in sorted(Path(sys.argv[1], "render").glob("*/manifest.json")):
    imgs = json.loads(man.read_text())["images"]
    n = sum(bool(e.get("complete")) for e in imgs.values())
    print(f"{sys.argv[1]}: {man.parent.name}: {n}/{len(imgs)} images complete")
    done += n; total += len(imgs)
print(f"{sys.argv[1]}: {done}/{total} images rendered; report: {Path(sys.argv[1], 'report.md').exists()}")
PY
}

timed() {  # timed NAME TIMEOUT_S CMD...: runs CMD, records its wall time and exit code in NAME.time
  local name=$1 limit=$2; shift 2
  local t0=$(date +%s.%N)
  timeout "$limit" "$@" > "$OUT/$name.log" 2>&1; local rc=$?
  local t1=$(date +%s.%N)
  echo "$name rc=$rc wall_s=$(python3 -c "print(round($t1 - $t0, 1))")" | tee "$OUT/$name.time"
  tail -3 "$OUT/$name.log"
}

echo "== 1. the main job, cold then warm ($VARIANT, -j $J)"
timed run_cold $(( $(left) > 240 ? 240 : $(left) )) edgetruth run --variant "$VARIANT" -j "$J" -o A --no-progress
timed run_warm $(( $(left) > 200 ? 200 : $(left) )) edgetruth run --variant "$VARIANT" -j "$J" -o B --no-progress

compare() {  # compare DIR_A DIR_B: every file hash of every manifest, the first differing EXRs' pixels, the rows
python3 - "$1" "$2" <<'PY' | tee -a "$OUT/identical.txt"
import csv, json, sys
from pathlib import Path
A, B = Path(sys.argv[1]), Path(sys.argv[2])
same = differ = shown = 0
for man in sorted((A / "render").glob("*/manifest.json")):
    a = json.loads(man.read_text())["images"]
    other = B / man.relative_to(A)
    b = json.loads(other.read_text())["images"] if other.exists() else {}
    for name, e in a.items():
        for kind, f in e.get("files", {}).items():
            if b.get(name, {}).get("files", {}).get(kind, {}).get("sha256") == f["sha256"]:
                same += 1
                continue
            differ += 1
            if kind == "exr" and shown < 3:
                shown += 1
                try:  # how far apart: the pixels that differ and by how much
                    from edgetruth.render.dataset.files import read_exr
                    x, y = read_exr(man.parent / f["path"]), read_exr(other.parent / f["path"])
                    d = x != y
                    print(f"differs: {man.parent.name}/{name}.exr: {int(d.sum())} of {d.size} pixels, "
                          f"max |diff| {float(abs(x - y).max()):.3g} on {float(abs(x).max()):.3g}")
                except Exception as err:
                    print(f"differs: {man.parent.name}/{name}.exr ({err})")
print(f"{A} vs {B}: render files identical: {same}, different: {differ}")
def rows(d):
    try:
        with open(d / "ranging_rows.csv") as f:
            return [{k: v for k, v in r.items() if k != "time_s"} for r in csv.DictReader(f)]
    except FileNotFoundError:
        return None
ra, rb = rows(A), rows(B)
print(f"{A} vs {B}: ranging rows: {len(ra or [])} and {len(rb or [])}, equal but for time_s: {ra is not None and ra == rb}")
PY
}

echo "== 2. byte-identical renders within the variant"
compare A B

# 2b. the evaluation alone, repeated on the same renders (a resumed run re-renders nothing): twice as it runs, twice
# with OpenCV on one thread.  On the H200 two runs' calibrations once differed by 2e-10 (fx) from identical images:
# OpenCV 5.0.0's calibrateCamera on several threads, now run on one (edgetruth/opencv_threads.py).
if [ "${EVAL_REPEAT:-1}" = 1 ] && [ "$(left)" -gt 200 ]; then
  echo "== 2b. the evaluation repeated on the same renders ($(left) s left)"
  for tag in e1 e2 t1 t2; do
    case $tag in t*) export OPENCV_FOR_THREADS_NUM=1 ;; *) unset OPENCV_FOR_THREADS_NUM ;; esac
    timed eval_$tag 120 edgetruth run --variant "$VARIANT" -j "$J" -o B --no-progress --skip-synthetic
    mkdir -p "E_$tag" && cp B/calibration.json B/ranging_rows.csv "E_$tag/" 2>/dev/null
  done
  unset OPENCV_FOR_THREADS_NUM
  python3 - <<'PY' | tee -a "$OUT/identical.txt"
import csv, json
from pathlib import Path
def load(tag):
    d = Path(f"E_{tag}")
    try:
        cal = json.loads((d / "calibration.json").read_text())
        with open(d / "ranging_rows.csv") as f:
            rows = [{k: v for k, v in r.items() if k != "time_s"} for r in csv.DictReader(f)]
        return cal, rows
    except FileNotFoundError:
        return None, None
runs = {t: load(t) for t in ("e1", "e2", "t1", "t2")}
for a, b, what in (("e1", "e2", "default threads"), ("t1", "t2", "OPENCV_FOR_THREADS_NUM=1")):
    (ca, ra), (cb, rb) = runs[a], runs[b]
    fx = (ca or {}).get("fx_px"), (cb or {}).get("fx_px")
    print(f"evaluation twice, {what}: calibration equal: {ca is not None and ca == cb} (fx {fx[0]!r} / {fx[1]!r}); "
          f"ranging rows equal but for time_s: {ra is not None and ra == rb}")
PY
fi

echo "== 3. the full study ($(left) s left)"
if [ "${FULL:-1}" = 1 ] && [ "$(left)" -gt 60 ]; then
  timed full $(( $(left) - 20 )) edgetruth run --study full --skip-synthetic --variant "$VARIANT" -j "$J" -o F --no-progress $FULL_ARGS
  progress F
fi
# 4. the full study again, where time is left, and its renders compared with the first (FULL_TWICE=0: skip)
if [ "${FULL:-1}" = 1 ] && [ "${FULL_TWICE:-1}" = 1 ] && [ "$(left)" -gt 150 ]; then
  echo "== 4. the full study again ($(left) s left)"
  timed full_again $(( $(left) - 20 )) edgetruth run --study full --skip-synthetic --variant "$VARIANT" -j "$J" -o G --no-progress $FULL_ARGS
  progress G
  compare F G
fi

# 5. the render bench, where time is left (BENCH=0: skip): the variants' samples/s on the bench window, R for
# docs/cluster.md's GPU formula, and the capacity plan (its log comes back in logs.tgz)
if [ "${BENCH:-1}" = 1 ] && [ "$(left)" -gt 200 ]; then
  echo "== 5. the render bench ($(left) s left)"
  timed bench $(( $(left) - 20 )) edgetruth bench --only render --repeats 1
  grep -E "^(render bench|dataset bench|capacity)" "$OUT/bench.log"
fi

# What comes back (at most 8 files, 16 MiB each): the log, the times, the checks, and per run one archive of
# its results without images and per-image truth (the manifests, with every file's hash, stay in).
pack() {  # pack RUN_DIR ARCHIVE [tar options]
  local d=$1 a=$2; shift 2
  [ -d "$d" ] && tar czf "$OUT/$a" -C "$d" --exclude='*.exr' --exclude='*.png' --exclude='render/*/[0-9]*.json' "$@" .
}
pack A run_cold.tgz
pack B run_warm.tgz --exclude=render_points.npz --exclude=synthetic --exclude=ranging_rows.csv
pack F full.tgz --exclude=render_points.npz  # ~40 MB for the full study; its summary CSV stays
tar czf "$OUT/logs.tgz" -C "$OUT" $(cd "$OUT" && ls *.log | grep -v gpu_check.log) && (cd "$OUT" && ls *.log | grep -v gpu_check.log | xargs rm -f)
cat "$OUT"/*.time > "$OUT/times.txt"
rm -f "$OUT"/*.time
ls -la "$OUT"
echo "gpu_check: done in $(( $(date +%s) - start )) s; results in $OUT"
