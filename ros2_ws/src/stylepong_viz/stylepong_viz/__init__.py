"""The cell, the teaching and the player in a browser (rerun web viewer), live from the graph or from a bag."""
