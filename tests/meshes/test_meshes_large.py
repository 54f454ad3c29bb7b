"""A 10-million-point scan builds without holding it in memory (read in chunks, voxelised early).

The same surface sampled with 1 M and with 10 M points must build with the same peak memory
give or take a fraction of what the 10 M points themselves would occupy: the absolute peak
depends on the machine (threads, allocator arenas), its growth with the point count does not.
About 25 s on 2 cores, so it stays in the fast set."""

import json
import subprocess
import sys
import textwrap

import numpy as np

from pipeline.meshes.io import write_ply_points


def lumpy_ball_mm(n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` float32 points on a lumpy 100 mm ball with 0.3 mm radial noise."""
    u = rng.normal(size=(n, 3)).astype(np.float32)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    r = 50 + 3 * np.sin(3 * u[:, :1]) + rng.normal(0, 0.3, (n, 1)).astype(np.float32)
    return (u * r).astype("<f4")


# The peak resident set of this process alone. Not getrusage's ru_maxrss: Linux carries that
# across fork and exec, so a child would report the (larger) peak of the pytest process.
PEAK_RSS_SOURCE = textwrap.dedent("""
    def peak_rss_mb():
        with open("/proc/self/status") as status:
            for line in status:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) / 1024
""")


def build_in_subprocess(scans, out) -> dict:
    """Build the scans in a fresh interpreter; its metrics and peak resident memory (MB)."""
    code = PEAK_RSS_SOURCE + textwrap.dedent(f"""
        import json
        from pipeline.meshes.build import build_meshes
        report = build_meshes({str(scans)!r}, {str(out)!r}, workers=1)
        scan = report.scans[0]
        print(json.dumps({{"status": scan.status, "message": scan.message,
                          "metrics": scan.metrics,
                          "max_rss_mb": peak_rss_mb()}}))
    """)
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                            timeout=600)
    assert result.returncode == 0, result.stderr
    out = json.loads(result.stdout.strip().splitlines()[-1])
    assert out["status"] == "built", out["message"]
    return out


def test_ten_million_points_build_in_bounded_memory(tmp_path):
    rng = np.random.default_rng(0)
    runs = {}
    for n in (1_000_000, 10_000_000):
        scans = tmp_path / f"scans_{n}"
        scans.mkdir()
        write_ply_points(scans / "huge.ply", lumpy_ball_mm(n, rng), units="mm")
        runs[n] = build_in_subprocess(scans, tmp_path / f"meshes_{n}")
    big = runs[10_000_000]
    assert big["metrics"]["points_in"] == 10_000_000
    assert big["metrics"]["points_after_downsample"] < 100_000
    assert big["metrics"]["max_edge_mm"] <= 3.0
    # 9 M more points: 108 MB as float32, 216 MB as float64, ~430 MB as an Open3D cloud with
    # normals. Chunked reading (1 M points per chunk) keeps the growth below the first; the larger
    # down-sampled cloud (the noise thickens the shell) accounts for part of what remains.
    growth_mb = big["max_rss_mb"] - runs[1_000_000]["max_rss_mb"]
    print(f"peak RSS 1 M: {runs[1_000_000]['max_rss_mb']:.0f} MB, 10 M: {big['max_rss_mb']:.0f} MB")
    assert growth_mb < 100, growth_mb
