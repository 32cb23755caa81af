"""The daemon: the service's wiring (``service``), its components (``components``), the job state
machine (``jobs``) and store (``store``, ``records``), the event bus, the configuration and the entry
point (``main``: the ``ribbond`` command). It imports the engine, never the API or the client; only
the entry point mounts the API."""
