"""Shared fixtures: the small datasets every Python test reads.

Under CTest the python.datasets fixture test has written them to $CHROMASIM_TEST_DATA.
Run by hand (`python3 -m pytest python/tests`), they are generated once per session with
$CHROMASIM_EXE (default build/release/chromasim) into a temporary folder.
"""

import os
import sys

import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))  # python/: the chromasim package
sys.path.insert(0, HERE)

import make_datasets  # noqa: E402


@pytest.fixture(scope="session")
def datasets(tmp_path_factory):
    out = os.environ.get("CHROMASIM_TEST_DATA")
    if not out:
        out = str(tmp_path_factory.mktemp("datasets"))
    exe = os.environ.get("CHROMASIM_EXE",
                         os.path.join(make_datasets.ROOT, "build", "release", "chromasim"))
    if not os.path.exists(exe):
        pytest.fail(f"{exe}: no chromasim executable; build it or set CHROMASIM_EXE")
    return make_datasets.make(exe, out)


@pytest.fixture(scope="session")
def quickstart(datasets):
    from chromasim.data import open_dataset
    return open_dataset(datasets["quickstart"])


@pytest.fixture(scope="session")
def sliding(datasets):
    from chromasim.data import open_dataset
    return open_dataset(datasets["tiny_sliding"])


@pytest.fixture(scope="session")
def chromasim_exe():
    exe = os.environ.get("CHROMASIM_EXE",
                         os.path.join(make_datasets.ROOT, "build", "release", "chromasim"))
    if not os.path.exists(exe):
        pytest.fail(f"{exe}: no chromasim executable; build it or set CHROMASIM_EXE")
    return exe
