"""Write the example scans of ``scans/``: a drainpipe, a rock pile and a branch, "scanned" by
a simulated depth sensor (noise, flying pixels, dropouts, outliers). Deterministic per seed.

    .venv/bin/python scripts/make_example_scans.py [--out scans] [--seed 0] [--truth DIR]

drainpipe.ply is binary PLY in mm (declared), rock_pile.pcd binary PCD in m (declared),
branch.xyz text in m (undeclared: the pipeline detects the units).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from pipeline.meshes.synthetic import write_example_scans


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("scans"))
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--truth", type=Path, default=None,
                        help="also write the reference meshes (OBJ, mm) here")
    args = parser.parse_args()
    for path in write_example_scans(args.out, seed=args.seed, truth_dir=args.truth):
        print(f"{path}  {path.stat().st_size / 1e6:.2f} MB")


if __name__ == "__main__":
    main()
