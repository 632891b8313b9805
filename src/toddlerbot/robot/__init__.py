"""Robot spec, model builder and transmissions (bottom layer: imports only toddlerbot.actuation)."""
