"""Building gaze maps from captured or keyframed example trials (Heck 5.2.1-5.2.2)."""
