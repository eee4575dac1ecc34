"""Hardware-in-the-loop serving: the simulated rack in real time on OS-level links.

``realtime`` paces the simpy environment to the wall clock and lets I/O threads inject host
input at the matching virtual time; ``pty_port`` owns raw ptys; ``serial_link``, ``slcan``
and ``socketcand`` speak the links; ``can_hub`` is the IEU's bus; ``link_map`` is the
``links.json`` file; ``server`` assembles them (``station serve``).
"""
