"""chromasim's Python tools: read a dataset written by `chromasim generate`, train and
evaluate safety-margin estimators on it, compute eigenstrains and draw figures.

Entry points (run with `python3 -m`, `python/` on PYTHONPATH or the package installed):
  chromasim.train       pretrain the seed-000 CNN (ShuffleNetV2) on a dataset
  chromasim.evaluate    stress-test any estimator's predictions CSV against a dataset
  chromasim.eigenstrain seed 001's SVD of strain fields and SVM classifiers
  chromasim.figures     the seeds' figures from a dataset and benchmark outputs

The readers (chromasim.data) need only numpy; torch is imported by train and the Dataset
class only.
"""

__version__ = "0.40.1"  # the CMake project version (python/tests/test_data.py checks it)
