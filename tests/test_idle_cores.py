"""The BLAS threads a fit takes: the cores the machine's load leaves, this process's own load aside."""

import os

import pytest

from gpmultirate import inference


@pytest.fixture
def machine(monkeypatch):
    """A two-core machine whose load average and this process's measured load are set."""

    def set_loads(load, own):
        monkeypatch.setattr(os, "cpu_count", lambda: 2)
        monkeypatch.setattr(os, "getloadavg", lambda: (load, load, load))
        monkeypatch.setattr(inference, "_OWN", {"wall": 1e300, "cpu": 0.0, "load": own})

    return set_loads


@pytest.mark.parametrize("load, own, idle", [
    (1.6, 1.6, 2),  # the fit alone, BLAS on two threads: its own load is no other work
    (1.0, 0.0, 1),  # an idle session and another process on one core
    (2.6, 1.6, 1),  # the fit and another process
    (0.3, 1.0, 2),  # the load has not caught up with this process yet
    (5.0, 1.0, 1),  # a busy machine: at least one
])
def test_idle_cores_leave_this_process_out_of_the_load(machine, load, own, idle):
    machine(load, own)
    assert inference.idle_cores() == idle


def test_own_load_is_cpu_time_over_wall_time_since_the_last_window(monkeypatch):
    clock = {"wall": 100.0, "cpu": 50.0}
    monkeypatch.setattr(inference.time, "perf_counter", lambda: clock["wall"])
    monkeypatch.setattr(inference.time, "process_time", lambda: clock["cpu"])
    monkeypatch.setattr(inference, "_OWN", {"wall": 100.0, "cpu": 50.0, "load": 1.0})
    clock.update(wall=102.0, cpu=53.0)
    assert inference.own_load() == 1.0  # under OWN_LOAD_WINDOW: the last measurement
    clock.update(wall=110.0, cpu=65.0)
    assert inference.own_load() == pytest.approx(1.5)  # 15 s of CPU in 10 s
    clock.update(wall=120.0, cpu=65.5)
    assert inference.own_load() == pytest.approx(0.05)
