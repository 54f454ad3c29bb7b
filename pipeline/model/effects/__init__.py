"""The physical effects of the whisker model, one module each (docs/architecture.md: how to add
an effect): its parameters (SI, :class:`~.base.Parameter`), how it changes the chain
(:class:`~.base.Effect` hooks), its per-link forces and their linearised form if it is a load
(:class:`~.loads.LoadEffect`); :mod:`.registry` maps the names configs use to the classes."""
