"""The youBot Monitor: a live web page for the youBot driver, fed by its host.

Part of the installed package (the wheel ships it, page and all), so that the youBot
composite's monitor component (``composites/youbot/monitor_component.py``) runs from a
plain ``pip install``; it is why ``plotly`` is a dependency of the package.

Use::

    from scart_monitor import MonitorServer, MonitorBackend

    server = MonitorServer(backend)          # backend: set_period / send_pose / poses
    server.start(); print(server.page_url)   # http://127.0.0.1:PORT/ (?token=... in token mode)
    server.set_driver_info("RUNNING", 0.01, connected=True)
    server.publish_status(status_dict)       # from any thread, as often as samples come
    server.publish_event("busy")             # busy / idle / refresh / reached / ...
    server.stop()                            # idempotent; ends streams, joins threads

The package knows nothing of the SCA runtime or of the remote layer: whoever hosts it
(an SCA component, a test, a script) pushes data in and answers the two commands.

The server answers only its own Host names (DNS rebinding), takes commands only with a
same-origin ``Origin`` (and, with ``token=``, the per-launch token), forbids framing and
caps streams and connections: see the Security section of :mod:`.server`. Non-browser
clients posting commands send ``Origin: http://127.0.0.1:PORT`` themselves.

Why this technology
-------------------
*A small page of ours on the standard library, Plotly.js from the ``plotly`` package.*

- **Server**: ``http.server.ThreadingHTTPServer``. The monitor serves one page, a JSON
  command per button and one event stream: a framework (NiceGUI/FastAPI/uvicorn) would add
  an asyncio loop, a websocket layer and a dozen dependencies to a runtime whose other
  parts are threads. With the stdlib the threads are ours: one accept thread created by
  `MonitorServer.start`, one per connection, all ended and joined by `MonitorServer.stop`.
- **Live data**: Server-Sent Events (``GET /events``). One-way push is all the page
  needs (commands are plain ``POST`` JSON), the browser reconnects by itself, and it is
  plain HTTP. The server keeps only the newest status and sends at most 25 updates/s per
  browser, so a driver at 1 kHz costs the page nothing and the driver never waits.
  Everything the page displays as a measurement (sample age, measured rate from the
  samples' own timestamps over 1 s, error flags decoded to names) is computed server-side.
- **Charts**: Plotly.js, a well-kept chart library, taken at run time from the installed
  ``plotly`` PyPI package (``plotly/package_data/plotly.min.js``) and served at
  ``/static/plotly.min.js``: nothing third-party is copied into this repository and no
  CDN is needed next to a robot with no internet. ``Plotly.extendTraces`` with a point
  cap scrolls the charts cheaply; the window (5/10/30/60 s) is an x-axis range.
- **Page**: ``static/index.html``, ``app.js``, ``style.css`` — no build step; the view
  (tab, window) lives in the URL hash so a reload or a shared link restores it.
"""

from .server import MonitorBackend, MonitorServer

__all__ = ["MonitorBackend", "MonitorServer"]
