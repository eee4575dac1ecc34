"""Client side of each instrument's protocol: one driver class per instrument, bound by URL;
laid out by laboratory (isu/, cigtf.py, esg.py) over the shared serial base and reply
grammars.
"""
