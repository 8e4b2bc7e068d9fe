"""Running the independent runs of a study: in this process, or through dask (a LocalCluster on this
machine's cores, or an existing scheduler)."""

import asyncio
import logging
import os
import signal
import tempfile
import threading
from contextlib import contextmanager

from tqdm import tqdm

from ..errors import InputError
from ..linalg.threads import thread_limit


class StudyInterrupted(KeyboardInterrupt):
    """Ctrl-C during `execute`: ``results[i]`` of every task that finished, None for the others."""

    def __init__(self, results: list):
        super().__init__()
        self.results = results


def execute(function, tasks: list, serial: bool = False, scheduler: str | None = None, echo=None,
            keep_going: bool = False, quiet: bool = True) -> list:
    """function(task) for every task, results in task order; through dask unless serial.

    Bigger runs are submitted with higher priority so that the longest one starts first.
    An InputError raised in a worker comes back as the same one-line error; with keep_going, a task that
    raises any error gives the result ``{"failed": one-line reason}`` and the others go on. Each task runs
    with one BLAS/OpenMP thread, in a dask worker as in this process: the workers share the
    cores, and run times measured either way are the same kind of number. Ctrl-C stops the
    runs under way and raises StudyInterrupted with the results of those that finished. Unless quiet, a
    :class:`Progress` bar counts the runs on stderr.
    """
    function = _catching(function, keep_going)
    results = [None] * len(tasks)
    with Progress(len(tasks), echo, quiet) as progress:
        try:
            if serial:
                for i, task in enumerate(tasks):
                    results[i] = _unwrap(function(task), keep_going)
                    _echo(progress, task, results[i])
            else:
                _distributed(function, tasks, scheduler, results, progress, keep_going)
        except KeyboardInterrupt:
            raise StudyInterrupted(results) from None
    return results


class Progress:
    """The progress of a study on stderr, drawn as a run's bar is (tqdm, from 2 s on, none when quiet): the runs
    done of the total, those failed, the time left (tqdm's, from the pace of the runs so far).

    ``echo(line)`` prints what the study prints of a run (a line; stress: a scene's result, through its own echo)
    above the bar, cleared and then drawn again below it; ``advance(failed)`` counts one run more. While the
    bar is on, femcrowd's log lines (the warnings of the runs) are printed above it the same way."""

    def __init__(self, total: int, echo=None, quiet: bool = True):
        self.bar = tqdm(total=total, disable=quiet, delay=2.0, desc="study",
                        bar_format="{l_bar}{bar}| {n}/{total} runs{postfix} [{elapsed}<{remaining}]")
        self.print = echo
        self.failed = 0

    @contextmanager
    def above(self):
        """What is printed in this context goes above the bar. A bar not yet drawn (the first 2 s) is left
        alone: clear() and refresh() would draw it."""
        drawn = not self.bar.disable and self.bar.last_print_t >= self.bar.start_t + self.bar.delay
        if drawn:
            self.bar.clear()
        try:
            yield
        finally:
            if drawn:
                self.bar.refresh()

    def echo(self, line) -> None:
        if self.print is not None:
            with self.above():
                self.print(line)

    def advance(self, failed: bool = False) -> None:
        if failed:
            self.failed += 1
            self.bar.set_postfix_str(f"{self.failed} failed", refresh=False)
        self.bar.update()

    def __enter__(self):
        self.log = logging.getLogger("femcrowd")
        self.handlers = self.log.handlers[:]
        if not self.bar.disable:
            self.log.handlers[:] = [_Above(self, self.handlers)]
        return self

    def __exit__(self, *exc):
        self.log.handlers[:] = self.handlers
        self.bar.close()


class _Above(logging.Handler):
    """The log's own handlers, their lines printed above a study's bar."""

    def __init__(self, progress, handlers):
        super().__init__()
        self.progress, self.handlers = progress, handlers

    def emit(self, record):
        with self.progress.above():
            for handler in self.handlers:
                if record.levelno >= handler.level:
                    handler.handle(record)


def _distributed(function, tasks, scheduler, results, progress, keep_going):
    """Fill results[i] = function(tasks[i]) through dask, in the order the runs finish."""
    import dask
    from dask.distributed import Client, LocalCluster, as_completed

    # dask's own logs unless -v: the outcome of every run comes back through its future, and what a worker
    # process logs when the study stops under it (a heartbeat to a scheduler already closed, after Ctrl-C) is
    # noise with a traceback
    verbose = logging.getLogger("femcrowd").isEnabledFor(logging.INFO)
    if not verbose:
        for name in ("distributed", "bokeh", "tornado"):
            logging.getLogger(name).setLevel(logging.ERROR)
    scratch = None
    if scheduler:
        client, cluster = Client(scheduler), None
    else:
        # the workers' scratch space (dask-scratch-space and its lock files) in a directory of this study's own,
        # removed when it ends, not left in the system's temporary directory
        scratch = tempfile.TemporaryDirectory(prefix="femcrowd-dask-")
        with _sigint_ignored(), dask.config.set({"temporary-directory": scratch.name}):
            cluster = LocalCluster(n_workers=os.cpu_count() or 1, threads_per_worker=1,
                                   processes=True, dashboard_address=":0",
                                   silence_logs=logging.ERROR if verbose else logging.CRITICAL + 1,
                                   local_directory=scratch.name)
        client = Client(cluster)
    try:
        futures = [client.submit(_in_worker(function), task, pure=False, priority=task.level) for task in tasks]
        index = {f.key: i for i, f in enumerate(futures)}
        for future in as_completed(futures):
            i = index[future.key]
            try:
                result = future.result()
            except Exception as err:   # the worker itself lost (killed, out of memory): that task alone
                if not keep_going:
                    raise
                result = failure(err)
            results[i] = _unwrap(result, keep_going)
            _echo(progress, tasks[i], results[i])
    except KeyboardInterrupt:
        if cluster is not None:   # the runs under way are dropped: stop their workers now (not after 4 s)
            cluster.sync(_stop_workers, list(cluster.workers.values()))
        raise
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
            scratch.cleanup()


async def _stop_workers(nannies):
    """Close the workers of these nannies at once, abandoning their tasks (dask waits 4 s for a busy worker)."""
    await asyncio.gather(*(nanny.close(timeout=0.5, reason="femcrowd-interrupted") for nanny in nannies))


@contextmanager
def _sigint_ignored():
    """SIGINT ignored while the LocalCluster's worker processes are spawned: they keep that disposition (an
    ignored signal survives exec, and Python then installs no KeyboardInterrupt handler), so a terminal's
    Ctrl-C, sent to the whole process group, is left to this process, which stops the study and keeps its
    finished runs. A Ctrl-C during these seconds of start-up is lost."""
    if threading.current_thread() is not threading.main_thread():   # only the main thread may set handlers
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def _in_worker(function):
    """function in a dask worker, whose tqdm (the progress bar of a run) locks with a thread lock: its default
    multiprocessing lock is a named semaphore, which a worker stopped on Ctrl-C would leave behind (and the
    resource tracker would then print a warning about it)."""
    def wrapped(task):
        from tqdm import tqdm
        tqdm.set_lock(threading.RLock())
        return function(task)
    return wrapped


def _unwrap(result, keep_going):
    if "input_error" in result and not keep_going:
        raise InputError(*result["input_error"])
    return result


def describe(task) -> str:
    """A task as the study's lines name it: a sweep member's values, a convergence run's series and level."""
    return task.series if task.out else f"{task.series}, level {task.level} ({task.mesh})"


def _echo(progress, task, result):
    """One run more on the bar, and the line of this one."""
    progress.advance("failed" in result)
    if "failed" in result:
        progress.echo(f"  failed: {describe(task)}: {result['failed']}")
    else:
        progress.echo(f"  done: {describe(task)}: {result.get('wall_seconds', result.get('wall', 0.0)):.2f} s")


def failure(err: Exception) -> dict:
    """The result of a task that raised `err`: its one-line reason (an InputError names file, key and value)."""
    text = " ".join(str(err).split()) or "(no message)"
    return {"failed": text if isinstance(err, InputError) else f"{type(err).__name__}: {text}"}


def _catching(function, keep_going):
    """function(task) with one BLAS thread; an InputError becomes a picklable result (InputError does
    not unpickle), and with keep_going any other error too."""
    def wrapped(task):
        try:
            with thread_limit(1):
                return function(task)
        except InputError as err:
            return {"input_error": (err.file, err.key, err.value, err.message), **failure(err)}
        except Exception as err:
            if not keep_going:
                raise
            return failure(err)
    return wrapped
