"""Wireshark integration: the generated XA-C1 dissector (``luagen``), its installer (``install``) and
the extcap live-capture entry point (``extcap``)."""
