"""The size of the BLAS and OpenMP thread pools, set by femcrowd for a run (threadpoolctl).

One controller for the process, made on first use (after numpy, scipy and cvxopt have loaded their
libraries); each ``limit`` is then cheap (microseconds, where ``threadpool_limits`` scans the loaded
libraries again: milliseconds).
"""

from threadpoolctl import ThreadpoolController

_controller = None


def thread_limit(threads: int):
    """A context in which the BLAS/OpenMP pools have `threads` threads."""
    global _controller
    if _controller is None:
        _controller = ThreadpoolController()
    return _controller.limit(limits=threads)
