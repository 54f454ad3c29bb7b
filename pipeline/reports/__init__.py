"""Reports: the natural tactile statistics of a dataset (``pipeline stats``) and the paper's
validation (``pipeline validate``). Each writes report.md, PNG figures and a JSON of its numbers.

matplotlib is imported (with the Agg backend) only by the figure modules.
"""
