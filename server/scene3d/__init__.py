"""The 3D view of each rover (viser): ``scene`` runs one viser server per rover and is a
frame sink, ``model`` draws the rover, terrain, traverses and vectors, ``proxy`` relays the
viewer's HTTP and WebSocket through the FastAPI app."""
