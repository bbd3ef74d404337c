"""The studies: each a short module that declares its options, runs, and writes its table and
figure through one skeleton (``sim.studies.base``); ``python -m sim.study NAME`` runs any."""
