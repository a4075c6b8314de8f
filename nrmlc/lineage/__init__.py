"""NRMLC's lineage, live: the sparse and subspace trackers the paper compares with, each as its
authors' public MATLAB code runs it, behind ``init(frame, box)`` / ``update(frame) -> box``.

``TRACKERS`` maps each short name (``nrmlc track --tracker ivt``, ``nrmlc benchmark --tracker
ivt``) to its factory, ``package.module:Class``; the benchmark runs them as any imported tracker
(:mod:`nrmlc.workbench.trackers`).
"""
from __future__ import annotations

#: Short name -> ``package.module:factory``.
TRACKERS = {
    "ivt": "nrmlc.lineage.ivt:IVTTracker",
    "asla": "nrmlc.lineage.asla:ASLATracker",
    "l1apg": "nrmlc.lineage.l1apg:L1APGTracker",
    "l1": "nrmlc.lineage.l1:L1Tracker",
    "mtt": "nrmlc.lineage.mtt:MTTTracker",
}
