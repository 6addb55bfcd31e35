"""Links: components that carry the runtime's state out of the process and
commands in (the recorder, the shore link over zenoh, MAVLink).

A link is a supervised component: it sends commands through the supervisor like
any other source and publishes what it hears on the bus; it sits above the
supervisor and below the composed settings, and nothing below imports a link.
"""
