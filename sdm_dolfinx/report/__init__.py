"""The HTML report of ``python -m sdm_dolfinx figures`` (``make figures``).

:mod:`.studies` composes what it computes (the paper's runs and the friction runs); :mod:`.build`
writes ``index.html`` (each figure next to what it should show and a verdict computed from our
numbers) and ``numbers.json`` (every number quoted) from one :class:`~sdm_dolfinx.study.entry.Entry`
per figure or study: the paper's own, :mod:`.table2_entry`, :mod:`.comparison_entry` (the method
comparison on GetFEM's rod) and :mod:`.hertz_entry` (the ball against Hertz).
"""
