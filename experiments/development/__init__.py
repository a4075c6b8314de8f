"""The development instruments: the development set, screens, the split and the diagnostics
that choose the defaults (docs/research/protocol.md)."""
