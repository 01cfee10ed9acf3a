"""The HTTP service: the job layer (``jobs``: store, workers, manager, quotas), the FastAPI
application (``server``) and its Python client (``client``)."""
