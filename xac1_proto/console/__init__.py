"""The interactive console's parts: command-line parsing (``commands``) and how exchanges are shown
(``show``); ``xac1_proto.cli.console_cmd`` is the prompt_toolkit shell around them."""
