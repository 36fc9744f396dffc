"""The sound service: impacts in, modal (or sampled, or synthesised) drum sound out at 48 kHz."""
