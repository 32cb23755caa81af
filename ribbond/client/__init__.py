"""The client: ``http`` talks to the daemon over HTTP (standard library only), ``cli`` is
``ribbonctl``. It imports the engine (for local designs), never the daemon or the API."""
