"""Generate the small datasets the Python tests read, with the chromasim executable.

Usage: python3 make_datasets.py CHROMASIM_EXE OUT_DIR
Writes OUT_DIR/quickstart (datasets_spec/quickstart.yaml: 2 trials, both fingertips, images)
OUT_DIR/tiny_sliding (specs/tiny_sliding.yaml: strain fields) and OUT_DIR/tiny_participants
(specs/tiny_participants.yaml: three sensors crossed with the grid). `chromasim generate`
does nothing for a folder that already holds the dataset of the same spec, so a second run
is cheap; a folder left by another spec or chromasim version (an earlier build in the same
build tree) is regenerated with --overwrite. CTest runs this once as the fixture of every
python.* test.
"""

import os
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
SPECS = {
    "quickstart": os.path.join(ROOT, "datasets_spec", "quickstart.yaml"),
    "tiny_sliding": os.path.join(HERE, "specs", "tiny_sliding.yaml"),
    "tiny_participants": os.path.join(HERE, "specs", "tiny_participants.yaml"),
}


def make(exe: str, out: str) -> dict[str, str]:
    os.makedirs(out, exist_ok=True)
    paths = {}
    for name, spec in SPECS.items():
        target = os.path.join(out, name)
        cmd = [exe, "generate", spec, "-o", target, "-q"]
        if os.path.exists(target + ".partial"):
            cmd.append("--resume")
        if subprocess.run(cmd).returncode != 0:
            if not os.path.isdir(target):
                sys.exit(f"make_datasets: {' '.join(cmd)} failed")
            # Refused: the folder holds another spec's or version's dataset.
            subprocess.run(cmd + ["--overwrite"], check=True)
        paths[name] = target
    return paths


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    make(sys.argv[1], sys.argv[2])
