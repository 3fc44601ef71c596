"""``edc-bench web``: the chain's history in a browser, read-only (docs/web.md).

Served from the history the station or the chain already has. On PostgreSQL a person signs in with their database
login, and the application reads as that login, so the database's roles decide what it may read; a station's
SQLite is served on 127.0.0.1 to whoever holds the access token printed at start. Pages are rendered on the server
(Starlette and Jinja2, every value escaped) with charts drawn by matplotlib as SVG: nothing loads from another
host, so a shop network without internet shows everything.
"""
