"""What the runs say: learning curves and final scores read from run directories
(:mod:`~physrover.analysis.curve_data`), tables with intervals and tests
(:mod:`~physrover.analysis.tables`) and figures (:mod:`~physrover.analysis.plots`).

May import: every wing below it (:mod:`physrover.experiment` and what it may import); it
reads run directories through :mod:`physrover.experiment.store`.
"""
