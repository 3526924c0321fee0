"""The experiments behind settings of `config/amp.yaml` (the discriminator's window length and frame
features); their records are indexed in experiments/README.md."""
