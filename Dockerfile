# syntax=docker/dockerfile:1
# Bilimovich Explorer: the web app (`bilimovich serve`) in a slim image. See docs/deployment.md.
#   docker build -t bilimovich-explorer .
#   docker run -p 5006:5006 -e BILIMOVICH_ALLOWED_ORIGINS=myhost:5006 bilimovich-explorer
# tests/deploy/test_dockerfile.py lints this file (hadolint) and runs its pip install,
# warmup, CMD and HEALTHCHECK commands in a fresh venv, so keep them plain shell commands.

ARG PYTHON_IMAGE=python:3.11.14-slim-bookworm

# --- build: the project and its dependencies in a venv (copied alone into the runtime stage) ---
FROM ${PYTHON_IMAGE} AS build
ENV PIP_DISABLE_PIP_VERSION_CHECK=1 \
    PIP_ROOT_USER_ACTION=ignore
RUN python -m venv /opt/venv
WORKDIR /src
COPY pyproject.toml README.md ./
COPY explorer_core ./explorer_core
COPY app ./app
# A regular (not editable) install without the test extra; the cache mount only speeds up
# rebuilds and never ends up in a layer.
RUN --mount=type=cache,target=/root/.cache/pip /opt/venv/bin/pip install .

# --- runtime ---
FROM ${PYTHON_IMAGE}
LABEL org.opencontainers.image.title="Bilimovich Explorer" \
      org.opencontainers.image.description="Web explorer of the inhomogeneous nonholonomic Bilimovich system" \
      org.opencontainers.image.licenses="BSD-3-Clause"
ENV PATH=/opt/venv/bin:$PATH \
    PYTHONUNBUFFERED=1 \
    HOME=/home/explorer \
    NUMBA_CACHE_DIR=/home/explorer/.cache/numba \
    MPLCONFIGDIR=/home/explorer/.cache/matplotlib \
    BILIMOVICH_ADDRESS=0.0.0.0 \
    BILIMOVICH_PORT=5006 \
    BILIMOVICH_SESSION_THREADS=4 \
    BILIMOVICH_PROCS=auto \
    BILIMOVICH_ALLOWED_ORIGINS=localhost:5006,127.0.0.1:5006
RUN useradd --no-log-init --create-home --home-dir /home/explorer --uid 10001 --user-group explorer
COPY --from=build /opt/venv /opt/venv
# Numeric, so a runtime that enforces non-root (Kubernetes runAsNonRoot) can verify it.
USER 10001:10001
WORKDIR /home/explorer
# Compile the numba kernels into NUMBA_CACHE_DIR as the user that serves, so the first
# visitor does not wait for them (a CPU unlike the build host's recompiles once, at start).
RUN mkdir -p "$NUMBA_CACHE_DIR" "$MPLCONFIGDIR" && bilimovich warmup
EXPOSE 5006
HEALTHCHECK --interval=30s --timeout=5s --start-period=60s --retries=3 \
    CMD ["python", "-c", "import os, urllib.request as u; u.urlopen('http://127.0.0.1:%s/liveness' % os.environ.get('BILIMOVICH_PORT', '5006'), timeout=4)"]
# Address, port, origins, threads and server processes (auto: one per CPU the container may use)
# come from the BILIMOVICH_* variables above (docker run -e ...).
CMD ["bilimovich", "serve"]
