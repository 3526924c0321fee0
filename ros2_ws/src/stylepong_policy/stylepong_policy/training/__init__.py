"""Training: demonstrations to a reference dataset, the table-tennis task on the batched world, the `train`
command, checkpoint choice and averaging, and `learn_style` with its skill library; the algorithms are in
`rl/`."""
