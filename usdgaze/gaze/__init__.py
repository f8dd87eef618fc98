"""The gaze model: displacement motions, map definitions, the parametric (Kovar-Gleicher) gaze map and the built-in human map."""
