"""Python tools and clients of the hapticloth haptic cloth server."""

__version__ = "0.1.0"
