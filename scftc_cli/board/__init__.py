"""The versioned leaderboard: ``models`` (what an entry is), ``store`` (validated reads, atomic
locked writes), ``draws`` (public and sealed episodes), ``ranking``, ``ops`` (submit, rebuild,
verify) and ``render`` (markdown, JSON, CSV)."""
