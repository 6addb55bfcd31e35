"""``zarco shore foxglove``: every vessel heard, live, on a Foxglove WebSocket
server with the recordings' topics and schemas (see :mod:`.bridge`), and the
layout that shows both (:mod:`.layout`)."""
