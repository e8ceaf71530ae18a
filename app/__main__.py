"""`python -m app`: serve the studio (see `app.cli`)."""

from app.cli import main

raise SystemExit(main())
