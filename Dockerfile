# SaddleScope: one image for the api, the workers and the one-shot migration.
FROM python:3.11-slim-bookworm

ENV PYTHONDONTWRITEBYTECODE=1 \
    PYTHONUNBUFFERED=1 \
    PIP_NO_CACHE_DIR=1 \
    PIP_DISABLE_PIP_VERSION_CHECK=1

# ffmpeg for phone videos of every flavour; libgl/libglib for OpenCV's video backends.
RUN apt-get update \
 && apt-get install -y --no-install-recommends ffmpeg libglib2.0-0 libgl1 curl \
 && rm -rf /var/lib/apt/lists/*

RUN useradd --create-home --uid 1000 saddlescope
WORKDIR /app

# Dependencies first, so code changes do not re-install them.
COPY pyproject.toml README.md ./
COPY backend/saddlescope/__init__.py backend/saddlescope/__init__.py
COPY worker/saddlescope_worker/__init__.py worker/saddlescope_worker/__init__.py
RUN pip install -e .

COPY alembic.ini ./
COPY backend ./backend
COPY worker ./worker
COPY frontend ./frontend
COPY deploy ./deploy
RUN pip install --no-deps -e .

ARG CODE_VERSION=""
ENV SADDLESCOPE_CODE_VERSION=${CODE_VERSION} \
    SADDLESCOPE_STORAGE_DIR=/data/storage
RUN mkdir -p /data/storage && chown -R saddlescope /data
USER saddlescope

EXPOSE 8000
CMD ["saddlescope", "serve", "--host", "0.0.0.0", "--port", "8000"]
