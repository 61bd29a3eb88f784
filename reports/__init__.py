"""Per-participant reports (HTML and PDF) rendered from a warehouse snapshot.

Imports only ``warehouse`` (and ``estimators``), so the nightly run's last step can call it through the command
line without ``pipeline`` importing ``dashboard``; the dashboard may import it too.
"""
