"""The split Hopkinson (Kolsky) pressure bar: the analysis of its bar waves.

:mod:`.waves` turns the strains that the gauges of the incident and transmitter bars
record into the specimen's stress, strain and strain rate (the 1-, 2- and 3-wave
analyses); the definitions and signs are in docs/shpb.md.
"""
