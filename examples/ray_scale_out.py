"""Scale out on Ray: the same render on a Ray cluster, byte for byte what one process writes.

Every image is a pure function of (spec, index), so where it renders does not change its bytes: `edgetruth
render SPEC -o DIR --backend ray [--address HOST:6379]` sends the tasks to a Ray cluster, and the driver
(this process) journals each finished image, so a run killed at any moment resumes. Without an address Ray
starts a local instance of this machine's cores (here 2 CPUs). This script renders a small spec both ways
and compares the manifests' file hashes. On a real cluster, pass its address (docs/cluster.md).

    python examples/ray_scale_out.py                 # 6 images at 160x128
    python examples/ray_scale_out.py --images 2      # what the tests run
"""
import argparse
import tempfile
from pathlib import Path

from edgetruth.render import open_dataset
from edgetruth.render.dataset.driver import render_spec

SPEC = """
[spec]
name = "scale_out"
camera = "quick"
camera_scale = 4
spp = 16
edge_spp = 64
sampler = "multijitter"

[[group]]
name = "circle"
target = "T2"
distance_range_cm = [60, 120]
count = {count}
irradiance_w_m2 = 0.0047
"""


class RayUnavailable(RuntimeError):
    """Ray is not installed, or cannot start a local instance here."""


def hashes(folder: Path) -> dict:
    """Every image's file hashes (SHA-256), from the dataset's manifest."""
    images = open_dataset(folder).manifest["images"]
    return {name: {k: f["sha256"] for k, f in e["files"].items()} for name, e in images.items()}


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--images", type=int, default=6, help="images to render (default 6)")
    ap.add_argument("--address", default=None, help="a Ray cluster's address (default: start a local one)")
    args = ap.parse_args(argv)
    try:
        import ray
    except ImportError as exc:
        raise RayUnavailable("ray is not installed: pip install 'edgetruth[cluster]'") from exc

    work = Path(tempfile.mkdtemp(prefix="edgetruth_ray_"))
    spec = work / "scale_out.toml"
    spec.write_text(SPEC.format(count=args.images))
    render_spec(spec, work / "local", progress=False, announce=lambda *a: None)   # one process
    if not ray.is_initialized():
        try:
            if args.address:
                ray.init(address=args.address, include_dashboard=False, log_to_driver=False)
            else:
                ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
        except Exception as exc:  # noqa: BLE001 -- any failure to start is "no Ray here"
            raise RayUnavailable(f"Ray could not start: {exc}") from exc
    try:
        timings = {}
        render_spec(spec, work / "ray", progress=False, announce=lambda *a: None, backend="ray",
                    timings=timings)
    finally:
        ray.shutdown()
    a, b = hashes(work / "local"), hashes(work / "ray")
    same = a == b
    print(f"{len(b)} images rendered on Ray (tasks per node: {timings.get('tasks_per_node', {})}); "
          f"identical to one process: {same}")
    return {"identical": same, "images": len(b)}


if __name__ == "__main__":
    main()
