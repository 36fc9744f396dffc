"""Graphics service: live 3D view in the browser, offline video frames, animation export.

See docs/graphics.md. ``core`` is deterministic (poses in, view frames out);
``node`` serves the page over HTTP and streams frames over a WebSocket.
"""
