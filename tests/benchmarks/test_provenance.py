"""A benchmark's results name the commit and the numerical libraries they came from."""

from __future__ import annotations

import numpy as np
import scipy
import sklearn
import trimesh

from benchmarks.provenance import environment, environment_line


def test_the_environment_is_the_one_running():
    env = environment()
    assert (env["numpy"], env["scipy"], env["scikit-learn"], env["trimesh"]) == (
        np.__version__, scipy.__version__, sklearn.__version__, trimesh.__version__)
    line = environment_line(env)
    assert f"numpy {np.__version__}" in line and f"scipy {scipy.__version__}" in line
    # the machine too: the BLAS's kernels and numpy's loops are chosen by the CPU
    assert env["cpu"] and f"CPU {env['cpu']}" in line
    assert "openblas" in env["blas"].lower() and f"BLAS {env['blas']}" in line


def test_a_result_of_a_run_before_the_machine_was_recorded_still_reads():
    line = environment_line({"commit": "4cf8cb8", "python": "3.11.7", "numpy": "2.4.6"})
    assert "commit 4cf8cb8" in line and "numpy 2.4.6" in line and "CPU" not in line


def test_a_result_without_an_environment_says_so():
    assert "not recorded" in environment_line(None) and "not recorded" in environment_line({})
