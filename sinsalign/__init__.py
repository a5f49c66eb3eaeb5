"""sinsalign: real-time initial alignment for strapdown inertial navigation systems.

Subpackages: ``sinsalign.service`` (alignment core and daemon), ``sinsalign.protocol`` (wire
and file formats), ``sinsalign.tools`` (simulator, replay, evaluation, benchmarks).
"""
__version__ = "0.1.0"
