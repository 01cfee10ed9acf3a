# Brush Studio: the 3D studio (viser, port 8080) and its HTTP API (port 8000) in one image.
#
#   docker build -t brush-studio .
#   docker run --rm -p 8080:8080 -p 8000:8000 -v brush-data:/data brush-studio
#
# Jobs, results and uploaded meshes live in the /data volume. Set BRUSH_STUDIO_TOKEN
# (docker run -e BRUSH_STUDIO_TOKEN=...) to require a bearer token on the API.
FROM python:3.11-slim

ENV PYTHONUNBUFFERED=1 \
    PIP_NO_CACHE_DIR=1 \
    PIP_DISABLE_PIP_VERSION_CHECK=1 \
    BRUSH_STUDIO_DATA=/data

# a non-root user owns the source tree (numba's kernel cache lives in engine/kernels/__pycache__)
RUN useradd --create-home --uid 1000 brush \
    && mkdir -p /app /data \
    && chown brush:brush /app /data

WORKDIR /app
COPY --chown=brush:brush . /app

# install: the package and its dependencies (editable, so that static_presets/ and the
# numba cache stay in /app)
RUN pip install --no-cache-dir -e .

USER brush

# warm-up: compile and cache the engine's numba kernels now, not on the first user's run
RUN brush-studio --version && brush-studio demo -o warmup --quiet && rm -rf warmup

VOLUME /data
EXPOSE 8080 8000

HEALTHCHECK --interval=30s --timeout=5s --start-period=60s --retries=3 \
    CMD python -c "import sys, urllib.request; sys.exit(0 if urllib.request.urlopen('http://127.0.0.1:8000/api/health', timeout=4).status == 200 else 1)"

# The studio in the browser (port 8080) with the HTTP API beside it (port 8000).
CMD ["brush-studio", "studio", "--host", "0.0.0.0", "--port", "8080", "--api-port", "8000", "--data", "/data"]
# Headless alternative (the HTTP API only, for scripted studies on servers):
# CMD ["brush-studio", "serve", "--headless", "--host", "0.0.0.0", "--port", "8000", "--data", "/data"]
