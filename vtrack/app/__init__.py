"""Applications that wire the layers together: the track pipeline and its config."""
