"""One ``APIRouter`` per component of the service; ``ribbond.api.app.create_app`` mounts them in
``ROUTERS``' order (the order of the paths in the OpenAPI document). Routes hold no business logic:
each calls one method of the service or of a component, and maps its result to a model."""
