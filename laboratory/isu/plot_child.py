"""What the day's plot child (laboratory.plot_worker) imports as the command line names the
command: the day's plots, and the all-positions fit it computes meanwhile (issue 17). Its
own module, which imports nothing, for both the command line and the run."""

PLOTS = "laboratory.isu.plots"  # the day's plots, drawn beside it
DAY_CHILD = (PLOTS, "procedures.isu.calibration.all_positions")
