"""Batch runs of the gaze pass: manifests, resume keys, local pools, dask clusters, farm job files."""
