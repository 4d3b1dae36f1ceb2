"""Loaded by the soak benchmark's server only (its PYTHONPATH): tracemalloc snapshots on request.

With ``SOAK_SNAPSHOTS`` set to a folder, Python's allocations are traced from the start and a
thread of its own writes ``<n>.snap`` (``tracemalloc.Snapshot.dump``) whenever the bench creates
``<n>.want`` there. Never part of the server: bench/bench_soak.py puts this folder on its path.
"""

import os

FOLDER = os.environ.get("SOAK_SNAPSHOTS")

if FOLDER:
    import threading
    import time
    import tracemalloc

    tracemalloc.start(int(os.environ.get("SOAK_FRAMES", "1")))

    def _serve():
        while True:
            for name in sorted(os.listdir(FOLDER)):
                if name.endswith(".want"):
                    stem = name[:-len(".want")]
                    snapshot = tracemalloc.take_snapshot().filter_traces(
                        (tracemalloc.Filter(False, tracemalloc.__file__),))
                    snapshot.dump(os.path.join(FOLDER, stem + ".part"))
                    os.replace(os.path.join(FOLDER, stem + ".part"), os.path.join(FOLDER, stem + ".snap"))
                    os.unlink(os.path.join(FOLDER, name))
            time.sleep(0.1)

    threading.Thread(target=_serve, name="soak-snapshots", daemon=True).start()
