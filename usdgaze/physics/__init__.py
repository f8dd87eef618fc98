"""Physics-based full body: an MJCF model from any UsdSkel skeleton, retargeting, MuJoCo dynamics."""
