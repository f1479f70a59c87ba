"""YARP's protocols in Python, with no YARP library: the name server's (``names``), the
port protocol with its ``tcp``, ``fast_tcp``, ``text`` and ``udp`` carriers (``wire``,
``dgram``, ``connection``, ``port``) and Bottles (``bottle``) — as YARP 3.5's sources define them.

A library of its own: it knows nothing of scart's ports and imports nothing of scart
(standard library only). scart's ``yarp`` transport is a thin adapter over it.

The story — a network, a port writing, a port reading, an RPC port, the end::

    from scart_yarp import Network

    net = Network(("127.0.0.1", 10000))          # or None: YARP's own configuration
    out = net.open_port("/arm/state")            # registered; `yarp read /r` then
    out.add_output("/r")                         # `yarp connect /arm/state /r`, or this
    out.write(["joints", [0.1, 0.2, 0.3]])       # every reader gets the bottle
    inp = net.open_port("/arm/cmd", reader=lambda msg: print(msg.source, msg.values()))
    rpc = net.open_port("/arm/rpc", responder=lambda cmd: ["ok", *cmd])   # `yarp rpc /arm/rpc`
    net.close()                                  # every port says q and unregisters

Threads, bounds and security are :mod:`scart_yarp.network`'s docstring.
"""

from __future__ import annotations

from .admin import admin_call, rpc_call
from .bottle import BottleError, Limits, Vocab
from .names import Contact, NameClient, NameServerError, name_server_address, parse_address
from .network import Network
from .port import Incoming, Port, PortLimits
from .wire import CARRIERS, ProtocolError

__all__ = ["CARRIERS", "BottleError", "Contact", "Incoming", "Limits", "NameClient", "NameServerError", "Network",
           "Port", "PortLimits", "ProtocolError", "Vocab", "admin_call", "name_server_address", "parse_address",
           "rpc_call"]
