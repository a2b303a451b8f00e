"""Global identifiability: how many values each unknown can take (SIAN's route, solved by msolve).

One job per module: :mod:`.rational` (the model's expressions as rational functions),
:mod:`.jets` (SIAN's differential equations as polynomials), :mod:`.truncation` (the finite
system the local test proves enough), :mod:`.sample` (the random point and the bound),
:mod:`.fibre` (the specialised system made zero-dimensional), :mod:`.msolve` (the solver, an
optional extra), :mod:`.values` (counts and symmetries read from the solutions),
:mod:`.functions` (functions of the unknowns asked about), :mod:`.result` (the answer),
:mod:`.run` (the whole question). The mathematics: docs/global.md.
"""
