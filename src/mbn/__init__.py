"""mbn: programmable fixed-weight CTRNNs and the Multiple Behavior Network.

A reproduction of Montone, Donnarumma & Prevete (ICANNGA 2011) as a reusable library.
"""

__version__ = "0.1.0"
