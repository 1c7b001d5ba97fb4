"""The lab: research applications built on the engine (validation, stiff suite, timing study,
work-precision, experiment, replay, reproduce, peers and exact references).

The lab imports the engine; the engine never imports the lab. Optional dependencies (scipy,
python-fcl, coal, matplotlib, dask, tqdm) are imported where they are used.
"""
