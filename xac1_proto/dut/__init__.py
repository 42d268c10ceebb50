"""A device under test, held safely: the shell that every command which drives a controller builds on.

``device`` is the one choke point for every byte sent (the motion guard, liveness), ``safety`` takes the
snapshot first and restores it last, ``settings`` says what a run may do (port, motion, safe range),
and ``evidence`` keeps what each probe sent and got back. ``xac1 conformance`` and ``xac1 replay`` use
it; it imports nothing of ``sniffer`` or ``conformance``. Importing the package loads no submodule.
"""
