"""Per-lap reports (HTML + PNG), summaries and MCAP export."""
