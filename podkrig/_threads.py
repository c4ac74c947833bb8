"""Thread-pool control for the online stage.

The online numerics (kriging of a few hundred points, GA populations, 24-reading misfits) are
many small BLAS calls; a multi-threaded BLAS only adds wake-up latency to them (an inversion took
0.87 s with two OpenBLAS threads against 0.57 s with one). :func:`one_blas_thread` limits BLAS to
one thread inside a ``with`` block and restores it afterwards.
"""

from threadpoolctl import ThreadpoolController

_CONTROLLER = None


def one_blas_thread():
    """Context manager limiting BLAS libraries to one thread.

    The controller is built once per process: scanning the loaded libraries costs milliseconds,
    too much per prediction call.
    """
    global _CONTROLLER
    if _CONTROLLER is None:
        _CONTROLLER = ThreadpoolController()
    return _CONTROLLER.limit(limits=1, user_api="blas")
