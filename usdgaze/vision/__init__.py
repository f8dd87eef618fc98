"""Vision: the eye model, the point of sight, the Kalman belief over objects, the attention costs."""
