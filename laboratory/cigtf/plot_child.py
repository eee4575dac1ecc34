"""What the gyrocompassing test's plot child (laboratory.plot_worker) imports as the command
line names the command (issue 17). Its own module, which imports nothing, for both the
command line and the run."""

PLOTS = "laboratory.cigtf.plots"  # the test's plot, drawn beside it
