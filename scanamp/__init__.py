"""scanamp: the application package (CLI, pipelines, demo, studies, reports).

The only package that imports all the others.
"""

__version__ = "0.1.0"
