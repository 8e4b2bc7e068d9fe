"""Running the independent runs of a study: in this process, or through dask (a LocalCluster on this
machine's cores, or an existing scheduler)."""

import logging
import os

from threadpoolctl import threadpool_limits

from ..errors import InputError


def execute(function, tasks: list, serial: bool = False, scheduler: str | None = None, echo=None) -> list:
    """function(task) for every task, results in task order; through dask unless serial.

    Bigger runs are submitted with higher priority so that the longest one starts first.
    An InputError raised in a worker comes back as the same one-line error. Each task runs
    with one BLAS/OpenMP thread, in a dask worker as in this process: the workers share the
    cores, and run times measured either way are the same kind of number.
    """
    function = _catching(function)
    if serial:
        results = []
        for task in tasks:
            results.append(_unwrap(function(task)))
            _echo(echo, task, results[-1])
        return results
    from dask.distributed import Client, LocalCluster, as_completed

    if not logging.getLogger("femcrowd").isEnabledFor(logging.INFO):   # dask's INFO chatter unless -v
        for name in ("distributed", "bokeh", "tornado"):
            logging.getLogger(name).setLevel(logging.ERROR)
    if scheduler:
        client, cluster = Client(scheduler), None
    else:
        cluster = LocalCluster(n_workers=os.cpu_count() or 1, threads_per_worker=1,
                               processes=True, dashboard_address=":0",
                               silence_logs=logging.ERROR)
        client = Client(cluster)
    try:
        futures = [client.submit(function, task, pure=False, priority=task.level) for task in tasks]
        index = {f.key: i for i, f in enumerate(futures)}
        results = [None] * len(tasks)
        for future in as_completed(futures):
            i = index[future.key]
            results[i] = _unwrap(future.result())
            _echo(echo, tasks[i], results[i])
        return results
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def _unwrap(result):
    if "input_error" in result:
        raise InputError(*result["input_error"])
    return result


def _echo(echo, task, result):
    if echo is not None:
        what = task.series if task.out else f"{task.series}, level {task.level} ({task.mesh})"
        echo(f"  done: {what}: {result.get('wall_seconds', result.get('wall', 0.0)):.2f} s")


def _catching(function):
    """function(task) with one BLAS thread; an InputError becomes a picklable result (InputError does
    not unpickle)."""
    def wrapped(task):
        try:
            with threadpool_limits(1):
                return function(task)
        except InputError as err:
            return {"input_error": (err.file, err.key, err.value, err.message)}
    return wrapped
