"""The blocks' trainings as Ray tasks: one task per block, retried from its checkpoint when its
worker dies, with their progress gathered by a small actor for one display in the driver.

Ray is an optional extra (``pip install 'lidar-ts[blocks]'``); everything here imports it on use.
"""

from __future__ import annotations

import os
import resource
import socket
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path

from rig.errors import InputError

#: A block whose worker process dies (killed, out of memory, a lost node) is started again this
#: many times; each retry resumes from the block's last checkpoint.
BLOCK_RETRIES = 3
#: A task tells the driver its progress this many times over its iterations.
PROGRESS_REPORTS = 200
#: The file in a block's run folder that names the process training it (for users and tests).
WORKER_PID_FILE = "worker.pid"
#: The file in a block's run folder that receives its training log.
LOG_FILE = "train.log"


@dataclass(frozen=True)
class BlockJob:
    """What one Ray task trains: block ``index``'s scene folder into its run folder with ``config``
    (a plain :class:`~splat.config.TrainConfig` dump) on ``threads`` CPU threads."""

    index: int
    scene_dir: str
    run_dir: str
    config: dict
    threads: int


def import_ray():
    """The ``ray`` module, or a one-line error naming the extra that installs it."""
    try:
        import ray
    except ImportError:
        raise InputError(
            "training in blocks needs Ray, which is not installed: pip install 'lidar-ts[blocks]' "
            "(make setup installs it)",
            field="blocks",
        ) from None
    return ray


def connect(address: str | None, cpus: int | None):
    """Start a local Ray instance with ``cpus`` CPUs (None: all of this machine's) or join the
    cluster at ``address`` (``auto``: the one ``ray start`` runs here); returns the ``ray`` module."""
    ray = import_ray()
    if address and address != "auto":
        _check_reachable(address)
    if not ray.is_initialized():
        options = {"include_dashboard": False, "log_to_driver": False, "logging_level": "ERROR"}
        try:
            if address:
                ray.init(address=address, **options)
            else:
                # "local": a new instance even where a cluster runs (ray start), which --ray-address names
                ray.init(address="local", num_cpus=cpus or os.cpu_count(), **options)
        except (ConnectionError, RuntimeError, ValueError) as exc:
            raise InputError(f"cannot reach Ray ({exc})", field="ray-address") from None
    return ray


#: Seconds to wait for a cluster's head to answer before saying it cannot be reached (Ray itself
#: keeps retrying for minutes).
CONNECT_TIMEOUT_S = 10.0


def _check_reachable(address: str) -> None:
    """A one-line error naming ``address`` (``HOST:PORT``, optionally ``ray://``) when nothing
    listens there."""
    host, _, port = address.removeprefix("ray://").rpartition(":")
    try:
        with socket.create_connection((host, int(port)), timeout=CONNECT_TIMEOUT_S):
            return
    except ValueError:
        problem = "expected HOST:PORT, e.g. 10.0.0.5:6379 as ray start --head prints it"
    except OSError as exc:
        problem = f"{exc.strerror or exc}; is ray start --head running there?"
    raise InputError(f"cannot reach a Ray cluster at {address} ({problem})", field="ray-address")


def cluster_cpus(ray) -> int:
    """CPUs the connected Ray cluster offers."""
    return max(1, int(ray.cluster_resources().get("CPU", 1)))


def train_block(job: BlockJob, board) -> dict:
    """Train one block (in a Ray worker): resumes from the block's checkpoint when an earlier
    attempt left one; returns the run summary, the worker's peak resident memory and the iteration
    it resumed at (None for a fresh start)."""
    import torch

    from splat.config import validated
    from splat.run_dir import checkpoint_path
    from splat.trainer import train

    torch.set_num_threads(job.threads)
    run_dir = Path(job.run_dir)
    run_dir.mkdir(parents=True, exist_ok=True)
    (run_dir / WORKER_PID_FILE).write_text(str(os.getpid()))
    config = validated(job.config)
    resume = checkpoint_path(run_dir).is_file()
    step = max(1, config.iterations // PROGRESS_REPORTS)
    first_done: list[int] = []

    def report(done: int) -> None:
        if not first_done:
            first_done.append(done)
        if done % step == 0 or done == config.iterations:
            board.report.remote(job.index, done, config.iterations)

    with (run_dir / LOG_FILE).open("a") as log_file:

        def log(message: object) -> None:
            print(message, file=log_file, flush=True)

        started = time.perf_counter()
        result = train(job.scene_dir, run_dir, config, resume=resume, progress=False, log=log,
                       on_iteration=report)  # fmt: skip
        wall = time.perf_counter() - started
    resumed_at = first_done[0] - 1 if resume and first_done else None
    return {
        "summary": asdict(result),
        "wall_s": round(wall, 3),
        "peak_rss_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1),
        "pid": os.getpid(),
        "resumed_at": resumed_at,
    }


class ProgressBoard:
    """Iterations done per block, written by the tasks and read by the driver (a Ray actor)."""

    def __init__(self) -> None:
        self.done: dict[int, tuple[int, int]] = {}

    def report(self, index: int, done: int, total: int) -> None:
        self.done[index] = (done, total)

    def read(self) -> dict[int, tuple[int, int]]:
        return dict(self.done)


def run_jobs(
    ray,
    jobs: list[BlockJob],
    *,
    gpus_per_job: float,
    on_progress: Callable[[dict[int, tuple[int, int]]], None],
    on_result: Callable[[int, dict], None],
) -> dict[int, dict]:
    """Run ``jobs`` as Ray tasks (each declares its threads as CPUs, and ``gpus_per_job`` GPUs) and
    return each one's result by block index; ``on_progress`` gets the board's reading about twice a
    second, ``on_result`` each block's result as it comes. A task whose worker dies is retried
    (:data:`BLOCK_RETRIES`); an error in the training itself (bad input, divergence) is not, and is
    raised as it was raised in the worker."""
    board = ray.remote(num_cpus=0)(ProgressBoard).remote()
    # max_calls=1: each block gets a fresh worker process, so its peak memory is its own.
    task = ray.remote(max_retries=BLOCK_RETRIES, retry_exceptions=False, max_calls=1)(train_block)
    pending = {
        task.options(num_cpus=job.threads, num_gpus=gpus_per_job).remote(job, board): job.index
        for job in jobs
    }
    run_dirs = {job.index: job.run_dir for job in jobs}
    results: dict[int, dict] = {}
    while pending:
        ready, _ = ray.wait(list(pending), num_returns=1, timeout=0.5)
        on_progress(ray.get(board.read.remote()))
        for ref in ready:
            index = pending.pop(ref)
            try:
                results[index] = ray.get(ref)
            except ray.exceptions.RayTaskError as exc:
                for other in pending:
                    ray.cancel(other, force=True)
                cause = exc.cause if isinstance(exc.cause, Exception) else exc
                raise cause from None
            except ray.exceptions.WorkerCrashedError:
                for other in pending:
                    ray.cancel(other, force=True)
                raise InputError(
                    f"block {index}'s worker died {BLOCK_RETRIES + 1} times; its checkpoint is kept: rerun "
                    "with --resume",
                    path=run_dirs[index],
                ) from None
            on_result(index, results[index])
    on_progress(ray.get(board.read.remote()))
    return results
