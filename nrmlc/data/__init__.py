"""Sequences: OTB folders, sparse-tracker packs, video files and synthetic videos.

Public API::

    open_sequence(path, target=None, init_box=None) -> Sequence   (a folder or a video file)
    list_sequences(root) -> list[Sequence]
    read_box_file(path) -> (n, 4) float64
    SyntheticSpec, SyntheticSequence(spec), synthetic_suite(...)
    write_otb_sequence(sequence, folder)
    VideoFileSequence(path, init_box=None)

A new layout is a module here that builds a :class:`Sequence` (or a subclass
that reads its own frames, like ``video_file.py``), hooked into ``open_sequence``.
"""
from nrmlc.data.boxes import read_box_file
from nrmlc.data.otb import list_sequences, open_sequence
from nrmlc.data.sequence import Sequence
from nrmlc.data.sparsepack import read_sparsepack_groundtruth
from nrmlc.data.synthetic import SyntheticSequence, SyntheticSpec, synthetic_suite, write_otb_sequence
from nrmlc.data.video_file import VideoFileSequence

__all__ = [
    "Sequence",
    "open_sequence",
    "list_sequences",
    "read_box_file",
    "read_sparsepack_groundtruth",
    "SyntheticSpec",
    "SyntheticSequence",
    "synthetic_suite",
    "write_otb_sequence",
    "VideoFileSequence",
]
