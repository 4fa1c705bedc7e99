"""The diagnosis on one base form (steps 2-5 of ``tuner.diagnosis.diagnose``), one module per step, all sharing
one record (``state.SearchState``):

- ``run``: the steps in order (``diagnose_on``, ``run``) and the detection limits (``detection``);
- ``state``: the shared record, a refitted model (``Fit``), the progress display's forecast and the residual
  floor's judgments;
- ``rows``: a refitted model's ranking row (held-out score, effect force, intervals) and its log line;
- ``reference``: the residual floor and evidence, and the base refitted alike ('none', the reference of every score);
- ``refits``: a candidate's screen and full refit;
- ``nonsmooth``: the nonsmooth candidates (a free play): refitted whatever the screen, the series element held,
  refitted before a residual is left without a cause;
- ``candidates``: the candidates' step (screen, refits, ranking rows);
- ``selection``: ranking, promotion, the lead's continuation, intervals and forward selection;
- ``form_steps``: the forms beyond the catalogue fitted, weighed with a cause and tried on top of the causes;
- ``conclusion``: from the ranking to the causes, and the result fields of ``diagnosis.json`` for the base.
"""
