"""Named experiments on an engine (MODEL.md §5). Each returns plain arrays and numbers."""
