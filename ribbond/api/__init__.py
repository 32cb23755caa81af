"""The HTTP API: ``app.create_app`` mounts one router per component (``routers``) over the service;
``models`` are the request and response bodies, ``errors`` maps the daemon's exceptions to statuses,
``guard`` checks every request before a route sees it."""
