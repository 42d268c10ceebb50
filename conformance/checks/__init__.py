"""The conformance checks, one module per protocol topic (run them with ``xac1 conformance``).

Each check's docstring states the rule it checks and the docs/protocol.md section; ``{id}`` in a docstring
stands for the check's parameter. Checks marked ``xac1_info`` record what the device does where the
protocol is silent and never fail.
"""
