"""USD at the edges: reading UsdSkel stages, writing override layers, the gaze schemas and their plugin."""
