"""Shore supervision over zenoh: telemetry out, commands in with one reply each,
the operator heartbeat, RTK corrections to the GPS; authenticated and
access-controlled (``[shore]``)."""
