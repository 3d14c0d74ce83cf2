"""The paper's simulations reproduced: runs, claims, metrics.json, report, figures (``smm-reproduce``).

``reproduce`` runs every scenario x controller into ``results``; ``acceptance`` checks the paper's claims on
them; ``metrics_json``, ``report`` and ``plots`` render them; ``cli`` is ``smm-reproduce``. The studies
(``tune_td``, ``energy_study``/``energy_report``, ``linearisation``), the retuned gain sets (``retuned``) and
the paper's published figures (``paper_values``) live beside them.
"""
