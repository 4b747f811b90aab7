"""Command-line tools (``hrn-vo SUBCOMMAND``)."""
