"""The batch fidelity: the campaign's recorded steps replayed for many trials at once, every
measurement and estimate an array over the trials (:class:`twin.batch.execute.BatchRun`)."""
