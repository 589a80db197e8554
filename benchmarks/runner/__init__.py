"""The sweep runner every study uses: cases on local processes or Dask, resumable, one results table; reports and timing."""
