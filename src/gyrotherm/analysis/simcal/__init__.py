"""The simulator calibrated to measured runs: parameters read off the measurements
(:mod:`._calibrate`, :mod:`._tang` for Tang et al.'s tables, :mod:`._bmi` for the BMI270
plateaus), each compared with its nulls on held-out statistics (:mod:`._nulls`), and
the replay of measured temperatures through the calibrated simulator
(:mod:`._simulate`)."""
