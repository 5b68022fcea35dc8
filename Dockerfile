# The grading image: robolab with every lab's reference solution, hidden tests and data,
# for sharded grading on a cluster (docs/instructor.md, "Grading on many machines").
#   docker build -t robolab .
#   docker run --rm -v "$PWD/course:/course" -e SHARDS=1 -e SUBMISSIONS=/course/submissions \
#       -e GRADES=/course/grades -e JOB_COMPLETION_INDEX=0 robolab
FROM python:3.11-slim
ENV PYTHONDONTWRITEBYTECODE=1 PIP_NO_CACHE_DIR=1 MPLBACKEND=Agg
WORKDIR /opt/robolab
COPY pyproject.toml README.md ./
COPY robolab/ robolab/
COPY solutions/ solutions/
COPY tests/ tests/
COPY notebooks/ notebooks/
COPY data/ data/
# editable: robolab finds solutions/, tests/labs/ and data/ beside its package
RUN pip install -e ".[instructor]" && robolab --version
COPY deploy/grade-shard.sh /usr/local/bin/grade-shard.sh
WORKDIR /course
CMD ["grade-shard.sh"]
