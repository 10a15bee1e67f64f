"""CPU priorities of a clinic's concurrent tasks (app.jobs.runner.EmbeddedRunner.priority_for)."""

from __future__ import annotations

import subprocess
import sys

from app.jobs.runner import SECOND_TASK_NICE, EmbeddedRunner


def test_a_clinics_second_concurrent_task_yields_to_another_clinics_first():
    runner = EmbeddedRunner(sessions=None, store=None, workers=2, job_timeout_s=60.0)  # not started: no pools
    assert runner.priority_for("clinic-a") == 0
    with runner.busy("clinic-a"):
        assert runner.priority_for("clinic-a") == SECOND_TASK_NICE
        assert runner.priority_for("clinic-b") == 0
        with runner.busy("clinic-b"):
            assert runner.priority_for("clinic-b") == SECOND_TASK_NICE
    assert runner.priority_for("clinic-a") == runner.priority_for("clinic-b") == 0
    assert runner.priority_for(None) == 0


def test_a_worker_task_runs_at_the_priority_it_is_given():
    probe = ("import os; from app.services.fitting import set_priority; set_priority(7); "
             "print(os.getpriority(os.PRIO_PROCESS, 0))")
    assert subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True).stdout.strip() == "7"
