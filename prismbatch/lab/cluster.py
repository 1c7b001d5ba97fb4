"""Dask execution of :func:`prismbatch.lab.validate` chunks and other lab tasks (optional extra ``[dask]``).

Chunks travel as ``(config, distribution, first block, number of blocks)``:
workers regenerate their pairs from the seed, so no arrays are shipped and
the merged results equal the in-process run's. Dask is imported only here.
"""

from __future__ import annotations

import contextlib
import os
import signal

__all__ = ["run_chunks", "run_tasks", "DASK_MISSING"]

DASK_MISSING = "running on Dask needs dask.distributed: pip install 'prismbatch[dask]'"


def _import_distributed():
    try:
        import distributed  # noqa: PLC0415
    except ImportError as exc:
        raise ImportError(DASK_MISSING) from exc
    return distributed


def _host_cpus():
    import socket

    return socket.gethostname(), os.cpu_count() or 1


def run_chunks(config, specs, done, *, scheduler=None, workers=None):
    """Run validation chunks on a Dask cluster and hand each result to ``done``.

    Parameters
    ----------
    config : dict
        Validation settings (:func:`prismbatch.lab.validate.make_config`).
    specs : list of tuple
        ``(distribution, first_block, n_blocks)`` per chunk.
    done : callable
        ``done(spec, chunk_result)``, called in the client as chunks finish
        (any order; the caller merges in block order).
    scheduler, workers
        As :func:`run_tasks`.

    Returns
    -------
    dict
        As :func:`run_tasks`.

    Notes
    -----
    The caller warms the Numba cache in-process first; each worker then loads
    the kernels (:func:`prismbatch.lab.validate.warm`) before chunks are submitted.
    """
    if scheduler is None and workers is None:
        raise ValueError("run_chunks needs a scheduler address or a number of workers")
    from .validate import run_chunk, warm

    return run_tasks(
        run_chunk,
        [(config, *spec) for spec in specs],
        lambda i, result: done(specs[i], result),
        warm=(warm, config["dtype"]),
        scheduler=scheduler,
        workers=workers,
        name="validate",
    )


def run_tasks(task, args, done, *, warm, scheduler=None, workers=None, name="tasks"):
    """Run ``task(*args[i], threads)`` for every i on a Dask cluster; ``done(i, result)`` as each finishes.

    Parameters
    ----------
    task : callable
        A module-level function (it travels by reference); its last argument is the
        Numba thread count the task should use.
    args : list of tuple
        The arguments of each task (small: settings and ranges, or the task's own inputs).
    done : callable
        ``done(i, result)``, called in the client as tasks finish (any order).
    warm : tuple
        ``(function, *arguments)`` run once on every worker before any task (loads or
        compiles the kernels there).
    scheduler : str, optional
        Address of an existing scheduler (``Client(address)``).
    workers : int, optional
        Without ``scheduler``: start ``LocalCluster(n_workers=workers,
        threads_per_worker=1, processes=True)`` and close it afterwards.
    name : str, optional
        Part of the task keys.

    Returns
    -------
    dict
        How the run was executed: scheduler, number of workers, Numba
        threads per task, and each worker's kernel warm-up seconds.

    Notes
    -----
    Every worker's Numba thread count is set to ``max(1, cpus of its host //
    worker threads on that host)``, so workers do not oversubscribe cores; the
    count is also passed to each task, because ``numba.set_num_threads``
    applies to the calling thread only.
    """
    if scheduler is None and workers is None:
        raise ValueError("run_tasks needs a scheduler address or a number of workers")
    distributed = _import_distributed()
    import logging

    from .validate import set_numba_threads

    cluster = None
    if scheduler is not None:
        client = distributed.Client(scheduler)
    else:
        with _workers_ignore_ctrl_c():
            cluster = distributed.LocalCluster(
                n_workers=int(workers),
                threads_per_worker=1,
                processes=True,
                dashboard_address=None,
                # task errors still reach the client; a stop must not print worker tracebacks
                silence_logs=logging.CRITICAL,
            )
        client = distributed.Client(cluster)
    futures = {}
    try:
        if scheduler is not None:
            client.wait_for_workers(1)
        info = client.scheduler_info()["workers"]
        hosts = client.run(_host_cpus)
        busy = {}
        for addr, (host, _) in hosts.items():
            busy[host] = busy.get(host, 0) + int(info[addr].get("nthreads", 1))
        per_worker = {addr: max(1, cpus // busy[host]) for addr, (host, cpus) in hosts.items()}
        for addr, k in per_worker.items():
            client.run(set_numba_threads, k, workers=[addr])
        # each worker loads (or compiles) the kernels before any task runs there
        warmup = client.run(*warm)
        threads = min(per_worker.values())
        for i, a in enumerate(args):
            fut = client.submit(task, *a, threads, pure=False, key=f"prismbatch-{name}-{i}-{os.getpid()}-{id(args)}")
            futures[fut] = i
        for fut in distributed.as_completed(list(futures)):
            done(futures[fut], fut.result())
        return {
            "scheduler": scheduler if scheduler is not None else "dask LocalCluster",
            "workers": len(hosts),
            "numba_threads": threads,
            "worker_warmup_s": {str(a): float(s) for a, s in warmup.items()},
        }
    except KeyboardInterrupt:
        # Stop cleanly: no task keeps running on the cluster, the local workers are shut down
        # (the finally below) instead of dying with the terminal's Ctrl-C.
        client.cancel(list(futures))
        raise
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


@contextlib.contextmanager
def _workers_ignore_ctrl_c():
    """Start worker processes with SIGINT ignored (they inherit it), then restore it here.

    Ctrl-C in a terminal reaches the whole process group; the client stops the workers itself,
    so they must not die half-way with their semaphores and files left behind.
    """
    try:
        old = signal.signal(signal.SIGINT, signal.SIG_IGN)
    except ValueError:  # not the main thread: signals are not ours to change
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, old)
