"""Evaluation: the protocol in the batched world (`evaluate`), its strokes, their DTW style and smoothness,
the blade at contact, and demonstrations or the player replayed against balls or onto the arm."""
