"""Checks that `import chromasim` (run with no PYTHONPATH, from /) gives the checkout in
argv[1] and its compiled module: what scripts/install-python sets up."""
import os
import sys

root = os.path.realpath(sys.argv[1])
try:
    import chromasim
    from chromasim import sim
except ImportError as e:
    sys.exit(f"import chromasim failed: {e}\nrun scripts/install-python (scripts/test does)")
where = os.path.realpath(chromasim.__file__)
if not where.startswith(os.path.join(root, "python") + os.sep):
    sys.exit(f"import chromasim gave {where}, not this checkout's {root}/python: "
             f"run scripts/install-python here (scripts/test does)")
core = os.path.realpath(sim._core.__file__)
if not core.startswith(os.path.join(root, "build") + os.sep):
    sys.exit(f"chromasim._core came from {core}, not {root}/build")
print(f"import chromasim: {where}, module {core} ({sim._core.build})")
