"""A plant model learned from every tick, and the model-based learner that searches it
between real episodes: the firmware library's ``RlsModel<S, A, R>`` and ``ModelBased<F, N>``
(``rust_type`` names each), so their records are the ones the board loads.

:class:`RlsModel` fits ``x' = x + Wᵀ·z``, ``z = [state, action, 1, features]``, by
regularised recursive least squares with forgetting, one tick at a time
(``model.update(state, action, next_state)``); ``features`` are up to two extra regressors
you compute yourself (``|v|·v`` for drag, ``sin θ`` for gravity) and pass with each tick
(the library's ``AffineWith``). ``model.predict(state, action)`` predicts the next state;
``model.rollout(start, ticks, policy)`` runs a closed-loop rollout of your policy on it.

:class:`ModelBased` proposes the θ of each real episode: ``learner.propose(predict)`` runs
the inner search (CMA-ES or a coordinate search) on ``predict(theta) -> float``, your
model's cost of θ (an imagined episode), inside a trust region around the best real θ, and
screens its best against ``reference + margin``; when the model's candidate does not pass,
the model-free fallback (a coordinate search or CMA-ES) proposes. ``learner.tell(cost)``
reports the real cost; ``learner.record(theta, cost)`` reports an episode you chose
yourself (the bare controller), ``learner.set_reference(cost)`` sets the screen's reference.

``predict`` may return ``nan`` or ``inf`` when the model cannot say (a diverging
rollout): the inner search ranks that θ worse than every prediction seen, as the library
does with a prediction error. An exception raised inside ``predict`` stops the proposal:
the learner and its RNG are left as they were before ``propose`` and the exception
propagates.

>>> import numpy as np, ctrl_adapt
>>> model = ctrl_adapt.RlsModel(1, 1)
>>> x = np.zeros(1)
>>> for k in range(200):
...     u = np.array([np.sin(0.3 * k)])
...     nxt = 0.9 * x + 0.5 * u
...     _ = model.update(x, u, nxt)
...     x = nxt
>>> model.rust_type, bool(abs(model.predict([1.0], [2.0])[0] - 1.9) < 1e-3)
('RlsModel<1, 1, 3>', True)
>>> real = lambda t: float(np.sum((t - [0.5, -0.2]) ** 2))
>>> learner = ctrl_adapt.ModelBased(-np.ones(2), np.ones(2), seed=1, margin=0.1,
...                                 initial_radius=0.3, inner_config={"max_evaluations": 120})
>>> learner.record(np.zeros(2), real(np.zeros(2)))
>>> learner.set_reference(real(np.zeros(2)))
>>> for _ in range(6):
...     theta, source, predicted = learner.propose(lambda t: real(t) + 0.01)
...     learner.tell(real(theta))
>>> bool(learner.best[1] < 1e-2), learner.rust_type
(True, 'ModelBased<CoordinateSearch<2>, 2>')
"""

from ._native import (
    MODEL_BASED_MAX_DIMENSION,
    MODEL_FEATURES,
    MODEL_MAX_ACTION,
    MODEL_MAX_STATE,
    ModelBased,
    ModelError,
    RlsModel,
)

__all__ = [
    "RlsModel",
    "ModelBased",
    "ModelError",
    "MODEL_MAX_STATE",
    "MODEL_MAX_ACTION",
    "MODEL_FEATURES",
    "MODEL_BASED_MAX_DIMENSION",
]
