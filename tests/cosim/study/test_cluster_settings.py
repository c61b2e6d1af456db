"""A study's local cluster stays nearly idle while its runs run: on a machine of as many
cores as workers, the scheduler's, the nannies' and the workers' periodic work is taken
from the runs (Dask's event-loop health check every 20 ms, the statistical profile of the
running task every 10 ms, the system monitor every 500 ms, the nannies' and workers'
memory check every 100 ms by default)."""

from __future__ import annotations

import json
import re

import pytest

from cosim.study.execution import cluster_settings

QUIET = """
import json
from cosim.study.execution import open_client

def worker(dask_worker):
    return [dask_worker._tick_interval, "profile" in dask_worker.periodic_callbacks,
            dask_worker.periodic_callbacks["monitor"].callback_time,
            dask_worker.periodic_callbacks["memory_monitor"].callback_time]

def nanny(dask_worker):
    return dask_worker.periodic_callbacks["memory_monitor"].callback_time

def scheduler(dask_scheduler):
    return [dask_scheduler._tick_interval,
            dask_scheduler.periodic_callbacks["monitor"].callback_time]

if __name__ == "__main__":
    with open_client(2) as client:
        found = {"workers": sorted(client.run(worker).values()),
                 "nannies": sorted(client.run(nanny, nanny=True).values()),
                 "scheduler": client.run_on_scheduler(scheduler)}
    print(json.dumps(found))
"""


@pytest.mark.slow
@pytest.mark.cluster
def test_a_local_cluster_ticks_slowly_and_profiles_nothing(run_python, tmp_path) -> None:
    script = tmp_path / "quiet.py"
    script.write_text(QUIET, encoding="utf-8")
    done = run_python(f"import runpy; runpy.run_path({str(script)!r}, run_name='__main__')")
    assert done.returncode == 0, done.stderr[-2000:]
    found = json.loads(done.stdout.strip().splitlines()[-1])
    # seconds between health checks; whether the task is profiled; ms between samples;
    # ms between memory checks
    assert found["workers"] == [[1.0, False, 5000.0, 500.0]] * 2, found
    assert found["nannies"] == [500.0] * 2, found
    assert found["scheduler"] == [1.0, 5000.0], found


def test_with_the_dashboard_the_workers_are_profiled_and_monitored() -> None:
    """The dashboard shows the profile and the monitor's samples: Dask's own settings."""
    assert cluster_settings(dashboard=True) == {
        "distributed.admin.tick.interval": "1s",
        "distributed.worker.memory.monitor-interval": "500ms",
    }
    assert cluster_settings(dashboard=False)["distributed.worker.profile.enabled"] is False


LINK = """
import io, re, urllib.request
from contextlib import redirect_stderr
from cosim.study.execution import open_client

if __name__ == "__main__":
    said = io.StringIO()
    with redirect_stderr(said), open_client(1, dashboard=True):
        link = re.search(r"Dask dashboard: (\\S+)", said.getvalue()).group(1)
        with urllib.request.urlopen(link, timeout=30) as page:
            print(link, page.status)
"""


@pytest.mark.slow
@pytest.mark.cluster
def test_a_local_cluster_with_the_dashboard_says_where_it_is_served(run_python, tmp_path) -> None:
    """The address printed is the one Dask serves (bokeh's dashboard, or Dask's page that
    names the bokeh it needs), on 127.0.0.1 only."""
    script = tmp_path / "link.py"
    script.write_text(LINK, encoding="utf-8")
    done = run_python(f"import runpy; runpy.run_path({str(script)!r}, run_name='__main__')")
    assert done.returncode == 0, done.stderr[-2000:]
    link, status = done.stdout.strip().splitlines()[-1].split()
    assert re.fullmatch(r"http://127\.0\.0\.1:\d+/status", link) and status == "200", link


# each nanny's look for its worker's word that it has started, recorded as it starts
# looking: the seconds between two looks
NANNY_LOOKS = """
import json
from distributed.nanny import WorkerProcess
from cosim.study.execution import open_client

looks = []
waiting = WorkerProcess._wait_until_connected

async def recorded(self, *args, **kwargs):
    looks.append(self._init_msg_interval)
    return await waiting(self, *args, **kwargs)

WorkerProcess._wait_until_connected = recorded
dask_own = WorkerProcess._init_msg_interval
if __name__ == "__main__":
    with open_client(2) as client:
        pass
    print(json.dumps([looks, dask_own, WorkerProcess._init_msg_interval]))
"""


@pytest.mark.slow
@pytest.mark.cluster
def test_a_local_clusters_nannies_see_their_workers_start_within_5_ms(run_python, tmp_path) -> None:
    """A nanny looks for its worker's word that it has joined the scheduler every 50 ms by
    Dask's default: up to 50 ms (25 on average) of every local study's start, after the
    last worker has joined and before the first run can be sent, with one worker as with
    two. Dask's own interval is back once the cluster has started."""
    script = tmp_path / "looks.py"
    script.write_text(NANNY_LOOKS, encoding="utf-8")
    done = run_python(f"import runpy; runpy.run_path({str(script)!r}, run_name='__main__')")
    assert done.returncode == 0, done.stderr[-2000:]
    looks, dask_own, after = json.loads(done.stdout.strip().splitlines()[-1])
    assert len(looks) == 2, looks
    assert all(look <= 0.005 for look in looks), f"the nannies looked every {looks} s"
    assert after == dask_own, (after, dask_own)


def test_two_clusters_starting_at_once_leave_dasks_nanny_interval_as_it_was() -> None:
    """Two studies of the Python API whose local clusters start at once (two threads of one
    process): the nannies look often until the last start has ended, and Dask's own
    interval is back after both, whichever ends first."""
    from distributed.nanny import WorkerProcess

    from cosim.study.execution import NANNY_LOOK_S, _nannies_look_often

    dask_own = WorkerProcess._init_msg_interval
    first, second = _nannies_look_often(), _nannies_look_often()
    first.__enter__()
    second.__enter__()
    first.__exit__(None, None, None)
    during = WorkerProcess._init_msg_interval
    second.__exit__(None, None, None)
    after = WorkerProcess._init_msg_interval
    WorkerProcess._init_msg_interval = dask_own  # (for the tests after this one)
    assert during == NANNY_LOOK_S, f"the second start's nannies look every {during} s"
    assert after == dask_own, f"after both starts the nannies look every {after} s"
