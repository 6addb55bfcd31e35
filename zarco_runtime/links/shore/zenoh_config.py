"""zenoh configurations of the shore protocol: the boat's peer and a shore client.

The key space is ``zarco/<vessel>/…``:

=========================  ==============  ==============================================
key                        direction       payload (UTF-8 JSON unless said otherwise)
=========================  ==============  ==============================================
``state``                  boat → shore    5 Hz vessel state
``health``                 boat → shore    1 Hz device health
``auv``                    boat → shore    per AUV track update
``event``                  boat → shore    per event
``map``                    boat → shore    on change and every 10 s; also a query
``access``                 shore → boat    query: operators get ``{"role": "operator"}``
``cmd/<name>``             shore → boat    query (zenoh get), one reply each
``operator``               shore → boat    operator heartbeat (≥ 1 Hz)
``rtcm``                   shore → boat    raw RTCM3 bytes for the GPS receiver
=========================  ==============  ==============================================

Access control (``auth`` usrpwd or mtls) denies by default; operators may
query ``cmd/**`` and ``access`` and put ``operator`` and ``rtcm``; viewers
may only subscribe to the telemetry; both may query ``map``.  Rules are
written per flow as seen from the boat: a viewer's subscription comes in
(ingress ``declare_subscriber``), telemetry goes out (egress ``put``), an
operator's query comes in and its reply goes out.

Operators are also told what the boat listens to: its subscriptions to
``operator`` and ``rtcm`` (egress ``declare_subscriber``) and its queryable
``cmd/**`` (egress ``declare_queryable``).  A zenoh client filters on the
write side: a declared publisher (``session.declare_publisher``, zenoh's
usual way to send a periodic value, the advanced publisher of
``zenoh.ext``) or a querier (``session.declare_querier``) sends only once
it knows that someone matches its key; without these declarations it sends
its first sample (before the boat's answer arrives) and drops every later
one.  ``session.put`` and ``session.get`` do not filter and need nothing.
Viewers are told nothing of the kind: they may not send anyway.
"""

from __future__ import annotations

from typing import Any

from zarco_runtime.links.shore.settings import Shore

TELEMETRY = ("state", "health", "auv", "event", "map")


def prefix(vessel: str) -> str:
    return f"zarco/{vessel}"


def access_control(cfg: Shore) -> dict[str, Any]:
    """The boat's zenoh access-control table for ``cfg.operators`` / ``cfg.viewers``."""
    v = prefix(cfg.vessel)
    rules = [
        {"id": "telemetry_out", "messages": ["put"], "flows": ["egress"],
         "permission": "allow", "key_exprs": [f"{v}/{k}" for k in TELEMETRY]},
        # a client may subscribe to the whole key space (a fleet view: zarco/*/state);
        # only the telemetry keys above are ever sent to it
        {"id": "subscribe", "messages": ["declare_subscriber"], "flows": ["ingress"],
         "permission": "allow", "key_exprs": ["zarco/**"]},
        {"id": "commands_in", "messages": ["query"], "flows": ["ingress"],
         "permission": "allow", "key_exprs": [f"{v}/cmd/**"]},
        {"id": "replies_out", "messages": ["reply"], "flows": ["egress"],
         "permission": "allow", "key_exprs": [f"{v}/cmd/**"]},
        {"id": "operator_in", "messages": ["put"], "flows": ["ingress"],
         "permission": "allow", "key_exprs": [f"{v}/operator", f"{v}/rtcm"]},
        # the boat's own declarations, announced to operators so that their
        # declared publishers and queriers send (write-side filtering)
        {"id": "listening_out", "messages": ["declare_subscriber"], "flows": ["egress"],
         "permission": "allow", "key_exprs": [f"{v}/operator", f"{v}/rtcm"]},
        {"id": "commands_out", "messages": ["declare_queryable"], "flows": ["egress"],
         "permission": "allow", "key_exprs": [f"{v}/cmd/**", f"{v}/map", f"{v}/access"]},
        # the map on demand (anyone), the role probe (operators)
        {"id": "map_query", "messages": ["query"], "flows": ["ingress"],
         "permission": "allow", "key_exprs": [f"{v}/map"]},
        {"id": "map_reply", "messages": ["reply"], "flows": ["egress"],
         "permission": "allow", "key_exprs": [f"{v}/map"]},
        {"id": "map_out", "messages": ["declare_queryable"], "flows": ["egress"],
         "permission": "allow", "key_exprs": [f"{v}/map"]},
        {"id": "access_query", "messages": ["query"], "flows": ["ingress"],
         "permission": "allow", "key_exprs": [f"{v}/access"]},
        {"id": "access_reply", "messages": ["reply"], "flows": ["egress"],
         "permission": "allow", "key_exprs": [f"{v}/access"]},
    ]
    field = "usernames" if cfg.auth == "usrpwd" else "cert_common_names"
    subjects: list[dict[str, Any]] = []
    policies: list[dict[str, Any]] = []
    if cfg.operators:
        subjects.append({"id": "operators", field: list(cfg.operators)})
        policies.append({"id": "operators", "subjects": ["operators"],
                         "rules": ["telemetry_out", "subscribe", "commands_in", "replies_out",
                                   "operator_in", "listening_out", "commands_out", "map_query",
                                   "map_reply", "access_query", "access_reply"]})
    if cfg.viewers:
        subjects.append({"id": "viewers", field: list(cfg.viewers)})
        policies.append({"id": "viewers", "subjects": ["viewers"],
                         "rules": ["telemetry_out", "subscribe", "map_query", "map_reply",
                                   "map_out"]})
    return {"enabled": True, "default_permission": "deny", "rules": rules,
            "subjects": subjects, "policies": policies}


def boat_config(cfg: Shore) -> dict[str, Any]:
    """The boat's zenoh configuration (a JSON object for ``zenoh.Config.from_json5``)."""
    c: dict[str, Any] = {
        "mode": "peer",
        "listen": {"endpoints": list(cfg.listen)},
        "connect": {"endpoints": []},
        "scouting": {"multicast": {"enabled": False}},
    }
    transport: dict[str, Any] = {}
    if cfg.auth == "usrpwd":
        transport["auth"] = {"usrpwd": {"dictionary_file": cfg.users_file}}
    tls: dict[str, Any] = {}
    if cfg.cert_file:
        tls.update(listen_certificate=cfg.cert_file, listen_private_key=cfg.key_file)
    if cfg.auth == "mtls":
        tls.update(root_ca_certificate=cfg.ca_file, enable_mtls=True)
    if tls:
        transport["link"] = {"tls": tls}
    if transport:
        c["transport"] = transport
    if cfg.auth != "none":
        c["access_control"] = access_control(cfg)
    return c


def client_config(endpoint: str, *, user: str = "", password: str = "", cert_file: str = "",
                  key_file: str = "", ca_file: str = "") -> dict[str, Any]:
    """A shore client's zenoh configuration for one boat endpoint: user/password,
    or a certificate and key (mutual TLS), and the CA that signed the boat's
    certificate (tls/ endpoints)."""
    c: dict[str, Any] = {
        "mode": "client",
        "connect": {"endpoints": [endpoint]},
        "scouting": {"multicast": {"enabled": False}},
    }
    transport: dict[str, Any] = {}
    if user:
        transport["auth"] = {"usrpwd": {"user": user, "password": password}}
    tls: dict[str, Any] = {}
    if ca_file:
        tls["root_ca_certificate"] = ca_file
    if cert_file:
        tls.update(connect_certificate=cert_file, connect_private_key=key_file,
                   enable_mtls=True)
    if tls:
        transport["link"] = {"tls": tls}
    if transport:
        c["transport"] = transport
    return c
