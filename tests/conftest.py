import os

# Figures render off screen. Set, not imported: importing matplotlib here would cost every
# grading run (one pytest process per submission) a quarter of a second.
os.environ["MPLBACKEND"] = "Agg"

pytest_plugins = ["robolab.grading.running.pytest_plugin"]
