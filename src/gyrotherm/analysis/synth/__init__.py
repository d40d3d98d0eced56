"""The independent synthetic generator the diagnosis is tested on: runs with known
effects in the catalogue's forms (:mod:`._synth`) and off the catalogue
(:mod:`._variants`: periodic, saturating, |ΔT|, rate-dependent hysteresis, ...), with
the truth of what was injected. Development and evaluation seeds are fixed in
``scripts/generalisation_sweep.py`` and the tests before any result."""
