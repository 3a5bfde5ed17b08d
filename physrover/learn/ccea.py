"""The cooperative coevolutionary algorithm with pluggable fitness (paper Algorithm 1).

One generation, everything batched over teams and rovers (R rovers, k policies each):

1. **Teams.** For each of the method's training rounds, a fresh random permutation of every
   population forms k teams, so each policy plays exactly once per round (the hall of fame
   instead pairs each policy with the best team found so far). The champion
   team (every population's best policy by the latest fitness) is added ``eval_episodes``
   times; all teams run as one batch of episodes on the vector env. Options from the lab's
   later code (``[learn]``): softmax team formation (:mod:`physrover.learn.teams`) and
   elite teams replayed after the training teams (:mod:`physrover.learn.team_elites`).
2. **Feedback.** Each policy's immediate feedback (its credit: D, G or a registered signal,
   :mod:`physrover.domain.scoring.credit`) and trajectory.
3. **Fitness** from the fitness method (D, G, average, leniency or a fitness critic).
4. **Evolution**: binary tournament with Cauchy mutation (:mod:`physrover.learn.evolution`),
   or the lab's n-elites tournament (``selection = "elites"``: the champion is elite 0).
5. **Critic update** (critic methods only), after evolution as in Algorithm 1.

Generations are counted from 1 everywhere (metrics.csv, progress, checkpoints, flags):
generation g is the g-th one run, and ``CCEA.generation`` is the number completed. The
learning curve is ``eval_G``: the mean G of the champion team on fresh episodes. The champion
evaluated in generation g was chosen by the fitness of generation g - 1 (in generation 1:
policy 0 of each population, i.e. an untrained team); it survived the tournament unchanged,
so evaluating it alongside generation g's training episodes costs no extra rollout. The
checkpoint after generation g (``champions/gen_g.npy``) holds the champion chosen by
generation g's fitness: the team that generation g + 1 would evaluate.

A ``[hybrid]`` table adds a gradient learner whose actors migrate into the populations
after evolution (:mod:`physrover.learn.hybrid`).

Random streams, all derived from ``seed``: policy initialisation, team permutations,
evolution, critic initialisation, critic mini-batches, the env's per-team start states,
and the hybrid's (a seventh child, so the first six are a plain run's).
"""

from __future__ import annotations

import json
import time

import numpy as np

from physrover.config import RunConfig
from physrover.core.compiled import dims
from physrover.core.trees import flatten, unflatten
from physrover.domain.scoring.credit import team_credit
from physrover.envs.gymnasium_env import RoverVectorEnv, generator_from_state, team_spaces
from physrover.learn.classes import team_layout
from physrover.learn.curriculum import CouplingCurriculum, recorded_G, replay_rules
from physrover.learn.eval_team import BestTeam
from physrover.learn.evolution import evolve, evolve_elites
from physrover.learn.fitness import Problem, make_method
from physrover.learn.hybrid import Hybrid
from physrover.learn.kernels import gather_trajectories
from physrover.learn.rollouts import mean_over_rollouts, repeat_teams
from physrover.learn.stats import GenerationStats
from physrover.learn.team_elites import TeamElites
from physrover.learn.teams import rank_teams, softmax_teams, team_genomes


class CCEA:
    """Algorithm 1 on a :class:`RoverVectorEnv`; ``run_generation`` advances one generation."""

    def __init__(self, config: RunConfig):
        self.config = config
        d, cfg = config.domain, config.learn
        self.n_rovers, self.k = d.n_rovers, cfg.population
        obs_space, action_space = team_spaces(d)  # sizes from the sensor and the domain
        n_obs, n_act = obs_space.shape[-1], action_space.shape[-1]
        self.layout = team_layout(cfg, d)  # one per agent class (learn.classes)
        *seeds, hybrid_seq = np.random.SeedSequence(cfg.seed).spawn(7)
        init_rng, self.team_rng, self.evo_rng, critic_init, self.critic_rng, env_seq = [
            np.random.default_rng(s) for s in seeds
        ]
        self.hybrid = Hybrid(config, hybrid_seq) if config.hybrid is not None else None
        self.genomes = self.layout.init((self.n_rovers, self.k), init_rng)
        self._team_genomes = None  # the teams' (E, R, P) genomes, one array reused
        self.team_elites = None  # the lab's elite teams (selection = "elites")
        if cfg.selection == "elites" and cfg.n_team_elites > 0:
            self.team_elites = TeamElites(cfg.n_team_elites, self.genomes, self.team_rng)
        self.n_elite_teams = 0 if self.team_elites is None else self.team_elites.n
        self.best_team = BestTeam() if cfg.eval_team == "best-team" else None
        problem = Problem(self.n_rovers, d.steps, n_obs, n_act)
        self.method = make_method(config, problem, critic_init)
        self.credit = team_credit(cfg.feedback, d)  # each agent's immediate feedback
        self.n_train = self.method.rounds * self.k
        self.n_played = self.n_train + self.n_elite_teams  # episodes before the evaluation's
        # a scenario redrawn per generation: the training teams (and elite teams) share one
        # start state and the champion's evaluation episodes draw fresh ones
        self.env = RoverVectorEnv(  # each played team's rollouts, then the evaluation's
            self.n_played * cfg.rollouts + cfg.eval_episodes, config=d,
            fresh_teams=cfg.eval_episodes, start_groups=cfg.rollouts)  # fmt: skip
        self.env.reset(seed=int(env_seq.integers(2**31)))
        self.curriculum = CouplingCurriculum.of(config)  # [learn] curriculum_start, or None
        if self.curriculum is not None:
            self.env.world.set_coupling(self.curriculum.n_req)
            self._rules = replay_rules(self.env.world)  # its rescoring's, built once
        self.fitness = np.zeros((self.n_rovers, self.k))
        self._pairs = None  # the trajectories' (s, a) pairs (_trajectories)
        # the fitness each policy carries into softmax team formation (NaN: not scored yet)
        self.carried = np.zeros((self.n_rovers, self.k))
        self.champion = np.zeros(self.n_rovers, dtype=np.int64)
        self.method.observe_champion(self.champion_genomes(), -np.inf)  # an untrained team
        self.generation = 0
        self.wall_seconds = 0.0
        self.timings = {"rollout": 0.0, "feedback": 0.0, "evolution": 0.0, "critic": 0.0}
        if self.hybrid is not None:
            self.timings["learner"] = 0.0  # training it and migrating

    # -- one generation ----------------------------------------------------------------------

    def rollout(self, genome_index: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Run one episode per row of (E, R) genome indices; returns G (E,) and each rover's
        credit (E, R), the configured signal (``[learn] feedback``, D by default).

        Index k and above address the method's extra genomes (the hall of fame), if any,
        then the elite teams (:meth:`_elite_index`).
        """
        table = self.genomes
        extra = self.method.extra_genomes()
        if extra is not None:
            table = np.concatenate([table, extra], axis=1)
        if self.team_elites is not None:
            table = np.concatenate([table, self.team_elites.table()], axis=1)
        if self._plays_best_team():
            table = np.concatenate([table, self.best_team.genomes[:, None]], axis=1)
        self._team_genomes = team_genomes(table, genome_index, self._team_genomes)
        policy = self.layout.prepare(self._team_genomes)  # (E, R, P) genomes
        world = self.env.play_episode(policy, headings=False)  # the CCEA reads no angle
        return world.G.copy(), np.array(self.credit(world), dtype=np.float64)

    def _after_populations(self) -> int:
        """The first rollout index past the populations and the method's extra genomes."""
        extra = self.method.extra_genomes()
        return self.k + (0 if extra is None else extra.shape[1])

    def _elite_index(self) -> np.ndarray:
        """(n_elite_teams, R) rollout indices of the elite teams: after the population and
        the method's extra genomes (then the best team, :meth:`_evaluated_index`)."""
        rows = self._after_populations() + np.arange(self.n_elite_teams)
        return np.broadcast_to(rows[:, None], (self.n_elite_teams, self.n_rovers))

    def _plays_best_team(self) -> bool:
        return self.best_team is not None and self.best_team.genomes is not None

    def _evaluated_index(self) -> np.ndarray:
        """(eval_episodes, R) rollout indices of the team the learning curve plays: the
        champion, or the best team (``eval_team``), after the elite teams."""
        if not self._plays_best_team():
            return np.broadcast_to(self.champion, (self.config.learn.eval_episodes, self.n_rovers))
        row = self._after_populations() + self.n_elite_teams
        return np.full((self.config.learn.eval_episodes, self.n_rovers), row)

    def _by_policy(self, per_team: np.ndarray, where: np.ndarray) -> np.ndarray:
        """(rounds, k, R) values by team -> (rounds, R, k) by policy; ``where[q, r, p]`` is
        the team in which policy p of rover r played in round q."""
        return np.take_along_axis(per_team.transpose(0, 2, 1), where, axis=-1)

    def _trajectories(self, where: np.ndarray) -> np.ndarray:
        """(R, k, T, D) trajectory of (s, a) pairs of each policy in round 0, from the
        world's (T, E, R, n_obs) observations and (T, E, R, 2) actions (D = n_obs + 2);
        ``where[r, p]`` is the team of policy p of rover r."""
        obs, act = self.env.world.trajectories()
        shape = (self.n_rovers, self.k, obs.shape[0], obs.shape[-1] + act.shape[-1])
        # One array kept across generations (overwritten by the next one): a fresh ~2 MB
        # array page-faulted every generation on the mixed team (glibc trimmed its heap).
        if self._pairs is None or self._pairs.shape != shape:
            self._pairs = np.empty(shape, dtype=np.float32)
        gather_trajectories(obs, act, where, self._pairs, dims(obs.shape[-1]))
        return self._pairs

    def _step_feedback(self, where: np.ndarray) -> np.ndarray:
        """(R, k, T) the credit signal of each policy's step t + 1 in round 0, taken alone
        (the step its pair t's action leads to; ``Credit.per_step``); ``where[r, p]`` is the
        team of policy p of rover r."""
        world = self.env.world
        per_step = self.credit.per_step(world)[1 : world.t + 1]  # (T, E, R)
        rovers = np.arange(self.n_rovers)[:, None]
        return np.ascontiguousarray(per_step[:, where, rovers].transpose(1, 2, 0))

    def run_generation(self) -> GenerationStats:
        cfg, R, k = self.config.learn, self.n_rovers, self.k
        rounds = self.method.rounds
        start = time.perf_counter()
        # order[q, r, m]: the policy of rover r in team m of round q.
        if cfg.team_formation == "softmax":
            order = softmax_teams(self.team_rng, self.carried, rounds, cfg.softmax_temperature)
        elif cfg.team_formation == "rank":
            order = rank_teams(self.carried, rounds)
        else:
            order = self.method.plan(self.team_rng, R, k)
        if self.hybrid is not None:  # [hybrid] together: the last migrants in one team
            self.hybrid.team_up(order, self.generation)
        team_index = order.transpose(0, 2, 1).reshape(rounds * k, R)
        played = repeat_teams(np.concatenate([team_index, self._elite_index()]), cfg.rollouts)
        G, credit = self.rollout(np.concatenate([played, self._evaluated_index()]))
        G = mean_over_rollouts(G, self.n_played, cfg.rollouts)
        credit = mean_over_rollouts(credit, self.n_played, cfg.rollouts)
        eval_G = float(G[self.n_played :].mean())
        train_n_req = 0
        if self.curriculum is not None:
            train_n_req = self.curriculum.train_n_req
            eval_G = self._curriculum_step(eval_G)
        t_rollout = time.perf_counter()

        where = np.argsort(order, axis=-1)  # where[q, r, p]: the team of policy p
        feedback = self._by_policy(credit[: self.n_train].reshape(rounds, k, R), where)
        team_G = np.broadcast_to(G[: self.n_train, None], (self.n_train, R))
        G_by_policy = self._by_policy(team_G.reshape(rounds, k, R), where)
        trajectories = None
        if self.method.needs_trajectories:
            trajectories = self._trajectories(where[0])
        if getattr(self.method, "needs_step_feedback", False):
            fitness = self.method.assign(
                feedback, G_by_policy, trajectories, step_feedback=self._step_feedback(where[0])
            )
        else:
            fitness = self.method.assign(feedback, G_by_policy, trajectories)
        t_feedback = time.perf_counter()

        # The team evaluated in this batch, before evolution can overwrite it.
        self.method.observe_champion(self.champion_genomes(), eval_G)
        if self.best_team is not None:  # the next generation's evaluated team
            elites = None if self.team_elites is None else self.team_elites.genomes
            self.best_team.pick(G, self.n_train, self.n_elite_teams, self.genomes, team_index,
                                elites)  # fmt: skip
        losers = None  # the tournament's (R, k // 2) overwritten slots
        if cfg.selection == "elites":
            self._evolve_elites(fitness, G, team_index, G_by_policy.mean(axis=0))
        else:
            _, losers = evolve(
                self.genomes,
                fitness,
                self.evo_rng,
                cfg.mutation_rate,
                cfg.mutation_scale,
                cfg.mutation,
            )
            survivors = np.where(np.isnan(fitness), -np.inf, fitness)
            survivors[np.arange(R)[:, None], losers] = -np.inf
            self.champion = survivors.argmax(axis=1)
            self.carried = fitness.copy()
            self.carried[np.arange(R)[:, None], losers] = np.nan  # the mutated copies
        self.fitness = fitness
        t_evolution = time.perf_counter()
        learner_G = float("nan") if self.hybrid is None else self.hybrid.migrate(
            self.generation + 1, self.genomes, self.carried, losers)  # fmt: skip
        t_learner = time.perf_counter()

        loss = self.method.update(self.critic_rng)
        end = time.perf_counter()

        spans = (t_rollout - start, t_feedback - t_rollout, t_evolution - t_feedback,
                 end - t_learner, t_learner - t_evolution)  # fmt: skip
        for name, seconds in zip(self.timings, spans, strict=False):  # learner: a hybrid's
            self.timings[name] += seconds
        self.wall_seconds += end - start
        stats = GenerationStats(
            generation=self.generation + 1,
            eval_G=eval_G,
            train_G_mean=float(G[: self.n_train].mean()),
            fitness_mean=float(np.nanmean(fitness)),
            critic_loss=loss,
            wall_seconds=self.wall_seconds,
            train_n_req=train_n_req,
            learner_G=learner_G,
        )
        self.generation += 1
        return stats

    def _curriculum_step(self, champion_G: float) -> float:
        """The champion's evaluation episodes at the domain's coupling (the learning
        curve), and the curriculum's rule on its G at the training coupling,
        ``champion_G`` (the coupling tightens for the next generation)."""
        world = self.env.world
        evaluated = slice(self.n_played * self.config.learn.rollouts, None)
        values = world.state.poi_values[evaluated]
        G = recorded_G(world, self.curriculum.target, evaluated, self._rules)
        if self.curriculum.observe(champion_G, float(values.sum(axis=1).mean())):
            world.set_coupling(self.curriculum.n_req)
        return float(G.mean())

    def _evolve_elites(self, fitness: np.ndarray, G: np.ndarray, team_index: np.ndarray,
                       team_G: np.ndarray) -> None:  # fmt: skip
        """The lab's n-elites selection (:func:`evolve_elites`) over the populations and the
        elite teams' members; then the next elite teams (:class:`TeamElites`). The champion
        is elite 0 of every population."""
        cfg = self.config.learn
        pool, pool_fitness, pool_team_G = self.genomes, fitness, team_G
        if self.team_elites is not None:
            members, member_fitness, member_team_G = self.team_elites.pool()
            pool = np.concatenate([self.genomes, members], axis=1)
            pool_fitness = np.concatenate([fitness, member_fitness], axis=1)
            pool_team_G = np.concatenate([team_G, member_team_G], axis=1)
            self.team_elites.select(
                G[self.n_train : self.n_played],
                self.genomes,
                team_index,
                G[: self.n_train],
                fitness,
            )
        self.genomes[...], self.carried = evolve_elites(
            pool, pool_fitness, self.k, cfg.n_individual_elites, self.evo_rng, cfg.mutation_rate,
            cfg.mutation_scale, cfg.mutation, pool_team_G, cfg.n_team_fitness_elites)  # fmt: skip
        self.champion = np.zeros(self.n_rovers, dtype=np.int64)

    def champion_genomes(self) -> np.ndarray:
        """(R, P) genomes of the team the learning curve plays next: the current champion
        (or the last best team, ``eval_team = "best-team"``)."""
        if self._plays_best_team():
            return self.best_team.genomes.copy()
        return self.genomes[np.arange(self.n_rovers), self.champion].copy()

    # -- checkpoints -------------------------------------------------------------------------

    def state(self) -> tuple[dict[str, np.ndarray], dict]:
        """Everything needed to continue bit-identically: (arrays, JSON-serialisable meta)."""
        arrays = {"genomes": self.genomes, "fitness": self.fitness, "champion": self.champion}
        if self.config.learn.team_formation != "random":
            arrays["carried"] = self.carried
        if self.team_elites is not None:
            arrays.update(self.team_elites.state())
        if self.best_team is not None:
            arrays.update(self.best_team.state())
        method_meta = {}
        for key, value in flatten(self.method.state()).items():
            if isinstance(value, np.ndarray):
                arrays[f"method/{key}"] = value
            else:
                method_meta[key] = value
        meta = {
            "generation": self.generation,
            "wall_seconds": self.wall_seconds,
            "rng": {
                name: getattr(self, name).bit_generator.state
                for name in ("team_rng", "evo_rng", "critic_rng")
            },
            "env_rng": self.env.rng_states(),
            "method": method_meta,
        }
        if self.curriculum is not None:
            meta["curriculum"] = self.curriculum.state()
        if self.hybrid is not None:
            hybrid_arrays, meta["hybrid"] = self.hybrid.state()
            arrays.update({f"hybrid/{key}": value for key, value in hybrid_arrays.items()})
        return arrays, json.loads(json.dumps(meta))

    def load_state(self, arrays: dict[str, np.ndarray], meta: dict) -> None:
        self.genomes[...] = arrays["genomes"]
        self.fitness = np.array(arrays["fitness"])
        self.champion = np.array(arrays["champion"])
        if "carried" in arrays:
            self.carried = np.array(arrays["carried"])
        if self.team_elites is not None:
            self.team_elites.load(arrays)
        if self.best_team is not None:
            self.best_team.load(arrays)
        flat = {k[len("method/") :]: v for k, v in arrays.items() if k.startswith("method/")}
        flat.update(meta["method"])
        self.method.load(unflatten(flat))
        self.generation = int(meta["generation"])
        self.wall_seconds = float(meta["wall_seconds"])
        for name, state in meta["rng"].items():
            setattr(self, name, generator_from_state(state))
        self.env.set_rng_states(meta["env_rng"])
        if self.curriculum is not None:
            self.curriculum.load(meta["curriculum"])
            self.env.world.set_coupling(self.curriculum.n_req)
        if self.hybrid is not None:
            hybrid = {k[len("hybrid/") :]: v for k, v in arrays.items() if k.startswith("hybrid/")}
            self.hybrid.load(hybrid, meta["hybrid"])
