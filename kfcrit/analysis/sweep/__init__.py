"""Parameter sweeps: the points, their checks, the resumable journal, and the local or Dask runner."""
