"""`python -m app`: serve the studio (see `app.cli`)."""

from app.cli import main

if __name__ == "__main__":  # not when a worker process (the map's) imports the main module
    raise SystemExit(main())
