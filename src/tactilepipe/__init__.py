"""tactilepipe: raw tactile recordings to models, metrics, figures and tables."""

__version__ = "0.1.0"
