"""The simulator's front panel in a browser (``xac1 sim --panel [HOST:]PORT``): a shell, never the model.

``server.Panel`` serves the page (``page.html``, self-contained), the JSON API and the live feed;
``state.state_of`` is the device state as JSON and ``line.LineWatch`` the line judged by the one
rulebook (both sans-IO). The server needs the ``panel`` extra (Starlette and uvicorn); importing this
package, ``state`` or ``line`` loads neither.
"""
