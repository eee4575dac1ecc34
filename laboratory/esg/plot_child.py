"""What the ESG calibration's plot child (laboratory.plot_worker) imports as the command line
names the command, and the modules of the jobs it is sent (issue 17). Its own module, which
imports nothing, for both the command line and the run."""

PLOTS = "laboratory.esg.plots"  # the schedules' plot, drawn beside the run
STUDY = "laboratory.esg.study"  # the strategy study and Figure 2, computed beside the run
STRATEGY = "procedures.esg.strategy"  # imported by the plot child only (scipy.optimize)
VARIANTS = "laboratory.esg.variants"  # the strategy variants and Figure 3, beside the run
