"""Executors: one protocol (:mod:`.executor`) for running an analysis's independent tasks in this process's
threads or on a Dask cluster (:mod:`.cluster`). Generic over the task: nothing here imports an analysis;
the analyses take an executor as an argument.
"""
