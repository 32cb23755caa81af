"""ribbond: design and print self-actuated surfaces from plastic ribbons on pre-stretched fabric."""

__version__ = "0.1.0"
