"""The text-to-material generator: accuracy on held-out objects, following the prompt, guidance, speed,
view coverage and failure cases (docs/generator.md)."""
