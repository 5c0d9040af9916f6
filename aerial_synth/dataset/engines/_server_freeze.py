"""Freezes the export's fork server's objects (imported by that server only, last).

Listed last among the modules the fork server imports before it forks any worker (see
:func:`aerial_synth.dataset.engines.fork_server.pool_context`): :func:`gc.freeze` moves every object the
server has created (the imported modules, ~1M objects) to the garbage collector's permanent
generation. A worker forked from the server shares those pages with it until it writes to
them, and a full collection in the worker would otherwise visit (and so write to) every
one of them: its first collections copy tens of MB of the server's heap page by page
(~11 000 page faults and 0.1 s of CPU measured on the first unpickling of a scene in a
freshly forked Dask worker) and every later full collection walks them again. Frozen
objects are never collected, which is what a module imported for the life of the worker
needs anyway.
"""

from __future__ import annotations

import gc

from ._server_guard import in_fork_server

FROZEN = False
if in_fork_server():
    gc.collect()
    gc.freeze()
    FROZEN = True
