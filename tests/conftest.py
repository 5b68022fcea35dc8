import matplotlib

matplotlib.use("Agg")

pytest_plugins = ["robolab.grading.pytest_plugin"]
