"""Links: components that carry the runtime's state out of the process and
commands in (the recorder, the shore link, MAVLink).  They sit above the
supervisor and below the composed settings; nothing below imports them."""
