"""Links from the runtime to the outside: shore supervision (zenoh), and others.

A link is a supervised component: it sends commands through the supervisor
like any other source and publishes what it hears on the bus; nothing below
(supervision, guidance, control, estimation, drivers) imports a link.
"""
