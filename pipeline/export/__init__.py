"""Taking results out of the warehouse: any table to CSV or Parquet (`stridelab.pipeline.export.tables`), and
recordings with their events to Motion-BIDS (`stridelab.pipeline.export.bids`). Both read the newest published
snapshot, never the live catalog, so an export runs beside a nightly run."""
