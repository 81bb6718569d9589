#!/usr/bin/env bash
# Issue 19's GPU check, on the device machine, from the repository root (docs/gpu.md):
#   python3 tools/device/prepare.py          # here: the wheels into .whl/ (ignored; carried)
#   bash tools/device/gpu_check.sh           # there, with `.whl` in carry; results under $OUT
# It installs the wheels (no index there) and, from a directory outside the checkout:
#   1. runs the main job twice (`edgetruth run`, the quick study) on VARIANT: cold, then with warm caches;
#   2. checks the two runs' renders are byte-identical (every file hash of every manifest) and their
#      ranging rows equal but for time_s;
#   3. runs the full study (`run --study full --skip-synthetic`) in the time left; a run cut short
#      resumes, and its images per second are recorded instead.
# Env: VARIANT (cuda_ad_rgb), BUDGET_S (whole script, 480), J (workers, the cores), FULL_ARGS (extra
# options for the full study, e.g. "--limit 2" for a dry run), SITE (where the wheels go).
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

echo "== 2. byte-identical renders within the variant"
python3 - <<'PY' | tee "$OUT/identical.txt"
import csv, json
from pathlib import Path
same = differ = 0
for man in sorted(Path("A/render").glob("*/manifest.json")):
    a = json.loads(man.read_text())["images"]
    other = Path("B") / man.relative_to("A")
    b = json.loads(other.read_text())["images"] if other.exists() else {}
    for name, e in a.items():
        for kind, f in e.get("files", {}).items():
            if b.get(name, {}).get("files", {}).get(kind, {}).get("sha256") == f["sha256"]:
                same += 1
            else:
                differ += 1
                if differ <= 5:
                    print(f"differs: {man.parent.name}/{name}.{kind}")
print(f"render files identical: {same}, different: {differ}")
def rows(d):
    try:
        with open(Path(d) / "ranging_rows.csv") as f:
            return [{k: v for k, v in r.items() if k != "time_s"} for r in csv.DictReader(f)]
    except FileNotFoundError:
        return None
ra, rb = rows("A"), rows("B")
print(f"ranging rows: {len(ra or [])} and {len(rb or [])}, equal but for time_s: {ra is not None and ra == rb}")
PY

echo "== 3. the full study ($(left) s left)"
if [ "$(left)" -gt 60 ]; then
  timed full $(( $(left) - 20 )) edgetruth run --study full --skip-synthetic --variant "$VARIANT" -j "$J" -o F --no-progress $FULL_ARGS
  python3 - <<'PY' | tee "$OUT/full_progress.txt"
import json
from pathlib import Path
done = total = 0
for man in sorted(Path("F/render").glob("*/manifest.json")):
    imgs = json.loads(man.read_text())["images"]
    n = sum(bool(e.get("complete")) for e in imgs.values())
    print(f"{man.parent.name}: {n}/{len(imgs)} images complete")
    done += n; total += len(imgs)
print(f"full study: {done}/{total} images rendered; report: {Path('F/report.md').exists()}")
PY
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
