"""The on-line inspection service (FastAPI): prepared models in memory, results to SQLite first.

Start it with ``shapeverify serve MODEL.svm`` or :func:`serve`; see :mod:`.app` for the endpoints.
"""

from shapeverify.service.app import ServiceConfig, create_app
from shapeverify.service.server import load_models, serve, warm_up

__all__ = ["ServiceConfig", "create_app", "load_models", "serve", "warm_up"]
