"""Named experiments on an engine (docs/model.md §5). Each returns plain arrays and numbers."""
