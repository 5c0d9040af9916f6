"""The export's worker processes: forks of one fork server that has imported what a worker
needs (:func:`pool_context`), used by the local pool (:mod:`.engines.pool`), the
LocalCluster's workers (:mod:`.engines.dask`) and the aggregate files' readers
(:mod:`.aggregate`)."""

from __future__ import annotations

from ...errors import EntryPointError

__all__ = ["WORKER_MODULES", "FORK_SERVER_PRELOAD", "pool_context", "start_pool_server", "check_entry_point"]


#: What a pool worker imports; the fork server imports it once, before it forks workers.
WORKER_MODULES = (
    "aerial_synth.dataset.engines._server_guard",  # first: see that module
    "aerial_synth.dataset.engines._server_open3d",  # before anything imports open3d
    "aerial_synth.numba_setup", "aerial_synth.dataset.worker", "aerial_synth.dataset.engines.pool",
    "aerial_synth.render.frame", "aerial_synth.render.backends.raycast", "aerial_synth.scene.hints",
    "aerial_synth.render.shading", "aerial_synth.render._kernels", "aerial_synth.render._tone",
    "aerial_synth.render._vis_kernels", "aerial_synth.render.smooth", "aerial_synth.render.raster",
    "aerial_synth.render.world",
    "aerial_synth.camera_rays", "aerial_synth.scene.raycast", "aerial_synth.placement.traffic",
    "aerial_synth.annotate", "aerial_synth.formats.registry", "aerial_synth.formats.coco",
    "aerial_synth.formats.dota", "aerial_synth.formats.meta", "aerial_synth.png",
    "isal.isal_zlib", "open3d", "scipy.special",
    # trimesh imports networkx in a try/except BaseException: a SIGTERM (the pool's stop,
    # Ctrl-C) landing in a worker during that import was swallowed, and the worker rendered
    # its whole task after Ctrl-C; imported here, no worker imports them
    "trimesh", "networkx", "shapely",
    "scipy.spatial", "scipy.ndimage", "cv2",
    "aerial_synth.dataset.engines._server_warm",  # last: see that module
)
#: What the export's fork server imports after the workers' modules when a ``--dask local:K``
#: cluster's workers fork from it (:func:`pool_context`): Dask distributed, then
#: :mod:`._server_freeze` (last: it freezes the server's objects so that a forked worker's
#: garbage collections do not copy the server's heap: 0.1 s of CPU per worker on its first
#: scene alone).
FORK_SERVER_PRELOAD = ("distributed", "aerial_synth.dataset.engines.dask", "aerial_synth.dataset.engines._server_freeze")


def pool_context(dask: bool = False):
    """The start method of the export's worker processes: a fork server where the platform
    has one (Linux, macOS), else spawn.

    A spawned worker starts a fresh interpreter and imports open3d, numba, scipy and the
    renderer itself (~2 s of CPU each). The fork server does those imports once, in a
    process that has started no threads (so forking it is safe, unlike forking the
    exporter once open3d or numba run), and every worker is a fork of it: nothing to
    import. Workers still get everything else through pickled arguments, as with spawn.
    The server's objects are frozen last (:mod:`._server_freeze`: a worker's collections
    then never copy the server's heap). ``dask``: Dask distributed is preloaded before
    that (a ``--dask local:K`` cluster's workers are forked from the same server, see
    :data:`FORK_SERVER_PRELOAD`)."""
    import multiprocessing as mp

    if "forkserver" not in mp.get_all_start_methods():
        return mp.get_context("spawn")
    ctx = mp.get_context("forkserver")
    ctx.set_forkserver_preload(list(WORKER_MODULES) + list(
        FORK_SERVER_PRELOAD if dask else ("aerial_synth.dataset.engines._server_freeze",)))
    return ctx


def check_entry_point() -> None:
    """Refuse to run while a worker process imports the main module: a script without an
    ``if __name__ == '__main__'`` guard that exports (or writes aggregate files) would
    otherwise start again in each of its worker processes. Here the worker stops at once,
    without a traceback where it was forked from the export's fork server
    (:mod:`._server_guard`); its parent sees it die and says so in one line (the aggregate
    files are then made in the parent, see :meth:`.aggregate.MetaRecords.map`)."""
    import multiprocessing as mp

    if getattr(mp.current_process(), "_inheriting", False):
        raise EntryPointError("a worker process is importing the main module, which exports again: "
                              "a script that exports must guard its entry point with if __name__ == "
                              "'__main__'")


def start_pool_server(dask: bool = False) -> None:
    """Start the fork server now (it imports :data:`WORKER_MODULES` in the background,
    on another core, while this process loads the scene); a no-op with spawn. A server
    already running is kept (its imports are the first caller's)."""
    ctx = pool_context(dask)
    if ctx.get_start_method() == "forkserver":
        from multiprocessing import forkserver

        forkserver.ensure_running()
