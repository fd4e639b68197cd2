!> `&integrator method = 'auto'`: the kernel chooses the method of an adaptive run, and
!> reviews its choice as the run goes.
!>
!> The candidates are single-rate (the scene's formula, 'adams' by default) and, when the
!> scene has slow (joint) and fast (modal) coordinates, the multirate couplings
!> 'exponential' (not with a closed loop through a flexible body, which it refuses) and
!> 'response'. Each candidate runs on a copy of the model from the initial state over the
!> first `probe_share` of the run, at the scene's tolerances, with the dense output of the
!> run's rows (its cost differs between the methods: the exponential flow's closed form
!> against a polynomial); 'response' is left out when 'exponential' finished its probe
!> without freezing its response anew (response_left_out). Its CPU over the probe's second
!> half (past the start's small steps), scaled to the rest of the run, plus its CPU up to
!> there, predicts its run; the least prediction runs the scene. A probe that has taken
!> `race_margin` times the CPU of the fastest finished probe is stopped: its candidate is
!> slower; so is one whose steps have taken `far_margin` times the CPU the fastest finished
!> probe's steps took to reach the same time (after `far_steps` steps; the steppers'
!> making and start left out, which for the exponential flow is most of a short probe; the
!> start's small steps are compared with the other start's), and one whose CPU so far,
!> past a quarter of its probe, scaled to the whole run, is `far_run` times the least
!> prediction (a method several times slower over the run is seen early). A scene without
!> both kinds of coordinates runs single-rate with no probe. A run continued from a
!> checkpoint keeps the method that wrote it.
!>
!> The review: a method's cost can change as the motion does (the flexible chain's links
!> spin up, and the 'exponential' coupling renews its frozen response more often). Every
!> `review_share` of the run the CPU per simulated second of the window just run is
!> measured, less the CPU its rows' output took (one output call in `sampling` timed: their
!> constant cost, the energy columns' works, would hide a method's growing one). The
!> baseline is the cheapest window since the start or the last review; the first opens a
!> probe's length after a start (its small steps left out). `dear_windows` windows in a
!> row dearer than the baseline by `review_margin`, and by `switch_gain` times the running
!> method's lead (the next cheapest candidate's CPU rate over the running one's when last
!> measured: the probes' mean rates at the start, a stopped probe's up to its stop, counted
!> as at most race_margin dearer), call a
!> review when it can pay (pays): every candidate is probed from the state reached over
!> `review_probe` of the start's probe length, the running method first, no rows kept. One
!> whose CPU rate over its probe's second half is `switch_gain` times below the running
!> method's takes over the run there (its stepper started from the state reached). A
!> review that keeps the running method makes the window's rate the baseline only when the
!> running method still probed the cheapest (a growth every method shares); when another
!> probed cheaper by less than `switch_gain` the baseline stays, and the next dear windows
!> call the next review (one review's short probes are noisy: on the flexible chain at
!> 0.70 s, with error_norm 'state', 'adams' probed 1.42-1.63x below 'exponential',
!> against the gain of 1.2). At
!> most `max_reviews` reviews, none when less than `review_rest` probes' length of the run
!> is left.
module pymr_driver_method_choice
  use pymr_env_kinds, only : dp
  use pymr_env_error, only : error_type, fatal_error
  use pymr_env_clock, only : thread_cpu_time
  use, intrinsic :: iso_fortran_env, only : int64
  use pymr_env_text, only : fmt, itoa, json_escape
  use pymr_model_scene, only : scene_t, integrator_spec, flexible_loop
  use pymr_model, only : model_t
  use pymr_integrator_stepper, only : stepper_t, step_counts
  use pymr_io_checkpoint, only : checkpoint_stepper
  use pymr_driver_stepper_setup, only : make_stepper
  implicit none
  private
  public :: choose_method, method_of_checkpoint, method_choice_t, probe_run
  public :: lead_of, baseline_after_review

  !> Share of the run (from its start) each candidate is probed over; CPU beyond the fastest
  !> finished probe's at which a probe stops.
  real(dp), parameter :: probe_share = 0.03_dp, race_margin = 1.5_dp, far_margin = 2.0_dp
  integer, parameter :: far_steps = 10
  real(dp), parameter :: far_run = 10.0_dp
  integer, parameter :: max_candidates = 3
  !> A candidate's failure when response_left_out leaves it out of the start's probes.
  character(len=*), parameter :: left_out_note = "left out: 'exponential' kept its frozen response over its probe"
  !> Rows of dense output a probe keeps at most (beyond, its run starts again from 0).
  integer, parameter :: max_probe_rows = 20000
  !> Times in a probe at which its CPU so far is noted (its pace, for the far_margin rule).
  integer, parameter :: n_pace = 32
  !> The review: its window (share of the run), the growth of the CPU rate that calls a
  !> review, the gain a candidate must show to take over, the reviews at most and the dear
  !> windows in a row that call one, and the rest of the run (in probe lengths) below which
  !> no review is made.
  real(dp), parameter :: review_share = 0.04_dp, review_margin = 1.5_dp, switch_gain = 1.2_dp
  integer, parameter :: max_reviews = 3, dear_windows = 2
  !> One output call in `sampling` is timed, drawn at random.
  integer, parameter :: sampling = 8
  !> A review's probes' length, as a share of the start's (each review probes every
  !> candidate: at the start's length, three reviews would cost a quarter of the run).
  real(dp), parameter :: review_probe = 1.0_dp/3.0_dp
  !> What a review must be able to save over its cost (the estimate leaves out the probes'
  !> small starting steps, which cost as much again on the tanks).
  real(dp), parameter :: payback = 2.0_dp
  real(dp), parameter :: review_rest = 4.0_dp

  !> A probe: its stepper and model where it stopped, and the states of the rows it passed
  !> (every dt of &output; nr = -1: too many rows, or none kept); its CPU, its CPU and time
  !> (from its start) at its second half's start, the time it ran, and its pace (its CPU
  !> in its steps, past its stepper's making and start, to each n_pace-th of its length;
  !> huge where not reached).
  type :: probe_run
    class(stepper_t), allocatable :: st
    type(model_t), allocatable :: model
    real(dp), allocatable :: rows(:, :)
    integer :: nr = 0
    real(dp) :: cpu = 0.0_dp, cpu_half = -1.0_dp, t_half = 0.0_dp, t_run = 0.0_dp
    !> CPU of its stepper's making and start.
    real(dp) :: making = 0.0_dp
    real(dp) :: pace(n_pace) = huge(1.0_dp)
  end type probe_run

  !> What 'auto' chose and why: the candidates' labels and methods (set_method's numbers),
  !> probe CPU and predicted run CPU (s; huge when the probe failed or stopped) and why it
  !> did, the probe's end time.
  type :: method_choice_t
    integer :: n = 0, chosen = 0
    character(len=40) :: label(max_candidates) = ''
    integer :: method(max_candidates) = 0
    real(dp) :: cpu(max_candidates) = huge(1.0_dp), predicted(max_candidates) = huge(1.0_dp)
    !> Each probe's mean CPU rate (s per simulated s, its making included) over what it
    !> ran, finished or stopped (huge when it failed).
    real(dp) :: mean(max_candidates) = huge(1.0_dp)
    !> Each probe's stepper's making and start (CPU s): what a review pays again.
    real(dp) :: making(max_candidates) = 0.0_dp
    character(len=200) :: failure(max_candidates) = ''
    real(dp) :: t_probe = 0.0_dp
    character(len=:), allocatable :: reason
    !> The candidates' finished probes; the pace of the fastest.
    type(probe_run) :: runs(max_candidates)
    real(dp) :: pace(n_pace) = huge(1.0_dp)
    !> The scene as asked (its own formula and order, for the single-rate candidate).
    type(integrator_spec) :: asked
    !> The review (none without probes): the current window's start (time; < 0: not yet), the
    !> baseline CPU rate (the cheapest window's, s per simulated s; < 0: the next window
    !> gives it), the reviews made, the method first chosen, and what the reviews found
    !> (summary text, JSON).
    real(dp) :: t_window = -1.0_dp, base_rate = -1.0_dp
    !> The time from which the next first window opens: past a start's small steps, which
    !> the baseline would count (the probe's length after the start or a hand-over).
    real(dp) :: t_open = 0.0_dp
    !> The thread's CPU at the window's start; the output calls (the rows after a step) in
    !> the window, those timed (one in `sampling`, drawn by times_output: timing each would
    !> cost a tenth of a tank's run), and the CPU the timed ones took, which the caller adds.
    !> The output is left out of the window's rate: its constant cost (the energy columns'
    !> works) would hide a method's growing one.
    real(dp) :: cpu_window = 0.0_dp, output = 0.0_dp
    integer :: n_out = 0, n_timed = 0
    integer(int64) :: draw = 20001
    integer :: reviews = 0, first = 0
    !> Windows in a row dearer than the baseline by the review's threshold, and the lead of
    !> the running method when last measured: the CPU rate of the next cheapest candidate
    !> over its own (lead_of).
    integer :: dear = 0
    real(dp) :: lead = huge(1.0_dp)
    character(len=:), allocatable :: review_text, review_json
  contains
    procedure :: summary => choice_summary
    procedure :: json => choice_json
    procedure :: take_chosen
    procedure :: review_due
    procedure :: review
    procedure, private :: restart_window
    procedure :: times_output
    procedure :: reviewing
  end type method_choice_t

contains

  !> Choose the method of the scene sc (method 'auto') at the initial state x of the model,
  !> and set it in sc (method, coupling, formula).
  subroutine choose_method(sc, model, x, choice)
    type(scene_t), intent(inout) :: sc
    type(model_t), intent(in) :: model
    real(dp), intent(in) :: x(:)
    type(method_choice_t), intent(out) :: choice
    integer :: i
    choice%asked = asked_of(sc)
    ! the multirate couplings first: where they pay, their probes are short and stop the rest
    if (model%n_fast() > 0 .and. model%n_slow() > 0) then
      if (.not. flexible_loop(sc)) call add_candidate(choice, sc, 2)
      call add_candidate(choice, sc, 3)
    end if
    call add_candidate(choice, sc, 1)
    if (choice%n == 1) then
      choice%chosen = 1
      choice%reason = 'the scene has no ' // trim(merge('fast (modal)', 'slow (joint)', model%n_fast() == 0)) // &
        & ' coordinates: nothing to run at two rates'
    else
      choice%t_probe = probe_share*sc%scene%t_end
      choice%t_open = choice%t_probe
      do i = 1, choice%n
        if (response_left_out(choice, i)) cycle
        call probe(sc, model, x, i, choice)
      end do
      choice%chosen = minloc(choice%predicted(1:choice%n), 1)
      choice%reason = 'least predicted CPU'
      if (all(choice%predicted(1:choice%n) == huge(1.0_dp))) then
        choice%chosen = choice%n
        choice%reason = 'every probe failed: single-rate, whose run reports why'
      end if
    end if
    choice%first = choice%chosen
    choice%lead = lead_of(choice%mean(1:choice%n), choice%chosen, was_stopped(choice%failure(1:choice%n)))
    call set_method(sc, choice%asked, choice%method(choice%chosen))
  end subroutine choose_method

  !> Whether candidate i, 'response', is left out of the start's probes: 'exponential'
  !> finished its probe without freezing its linear response anew for stability (a renewal
  !> for accuracy alone leaves it out: on the flexible chain one came in the probe, and
  !> 'response''s probe then cost 7.5 ms of a 100 ms run to predict 1.4 times
  !> 'exponential''s CPU). Both couplings then
  !> carry the same frozen linear response of the modes, 'exponential' exactly in one flow
  !> per step, 'response' by explicit fast steps between the same extrapolated full
  !> evaluations; on the shipped scenes its probe never predicted the least CPU there, and
  !> cost as much as the chosen probe (tank: 0.14 of a 2.9 ms run). Where the response
  !> drifts within the probe (the flexible chain spinning at 10 rad/s from the start) it is
  !> probed, and chosen; every review probes it.
  logical function response_left_out(choice, i) result(out)
    type(method_choice_t), intent(inout) :: choice
    integer, intent(in) :: i
    type(step_counts) :: done
    out = .false.
    if (choice%method(i) /= 3 .or. choice%method(1) /= 2 .or. .not. allocated(choice%runs(1)%st)) return
    done = choice%runs(1)%st%counts()
    out = done%renewals == done%accuracy_renewals
    if (out) choice%failure(i) = left_out_note
  end function response_left_out

  !> The integrator settings the candidates run with: the scene's, with error_norm
  !> 'amplitude' when the scene gives none and its modes allow it (no closed loop through
  !> a flexible body). 'state' holds a mode's coordinate to atol where it passes 0, which
  !> at loose tolerances bounds the steps whatever rtol asks: on the tank 'auto' took 1.3-1.6
  !> times the CPU of 'amplitude' at the same error, 1e-5 to 1e-8 m of muzzle motion.
  function asked_of(sc) result(asked)
    type(scene_t), intent(in) :: sc
    type(integrator_spec) :: asked
    asked = sc%integrator
    if (.not. sc%integrator%origin%given('error_norm') .and. .not. flexible_loop(sc)) asked%error_norm = 'amplitude'
  end function asked_of

  !> Method `method` of the scene sc (set_method's numbers) as the next candidate, with its
  !> label ("single-rate 'adams'", "multirate 'exponential'").
  subroutine add_candidate(choice, sc, method)
    type(method_choice_t), intent(inout) :: choice
    type(scene_t), intent(in) :: sc
    integer, intent(in) :: method
    choice%n = choice%n + 1
    choice%method(choice%n) = method
    select case (method)
    case (1)
      choice%label(choice%n) = "single-rate '" // trim(sc%integrator%formula) // "'"
    case (2)
      choice%label(choice%n) = "multirate 'exponential'"
    case default
      choice%label(choice%n) = "multirate 'response'"
    end select
  end subroutine add_candidate

  !> Set method i (1 single-rate, 2 'exponential', 3 'response') in sc, from the
  !> integrator settings as asked.
  subroutine set_method(sc, asked, i)
    type(scene_t), intent(inout) :: sc
    type(integrator_spec), intent(in) :: asked
    integer, intent(in) :: i
    sc%integrator = asked
    if (i == 1) then
      sc%integrator%method = 'single'; return
    end if
    sc%integrator%method = 'multirate'
    sc%integrator%formula = 'abm4'; sc%integrator%order = 4
    sc%integrator%coupling = trim(merge('exponential', 'response   ', i == 2))
  end subroutine set_method

  !> Candidate i from the initial state over [0, t_probe] on a copy of the model: its CPU
  !> (the stepper's making included) and its predicted run; the probe is kept (runs(i))
  !> when it finished.
  subroutine probe(sc, model, x, i, choice)
    type(scene_t), intent(in) :: sc
    type(model_t), intent(in) :: model
    real(dp), intent(in) :: x(:)
    integer, intent(in) :: i
    type(method_choice_t), intent(inout) :: choice
    real(dp) :: cap, most
    cap = huge(1.0_dp); most = huge(1.0_dp)
    if (i > 1) cap = minval(choice%cpu(1:i-1))
    if (cap < huge(1.0_dp)) cap = race_margin*cap
    if (i > 1) most = minval(choice%predicted(1:i-1))
    if (most < huge(1.0_dp)) most = far_run*most/sc%scene%t_end
    call race(sc, choice%asked, choice%method(i), model, 0.0_dp, x, choice%t_probe, cap, choice%pace, most, &
      & sc%output%dt, choice%runs(i), choice%failure(i))
    choice%mean(i) = mean_rate(choice%runs(i), choice%failure(i))
    choice%making(i) = choice%runs(i)%making
    if (len_trim(choice%failure(i)) > 0) return
    associate (run => choice%runs(i))
      choice%cpu(i) = run%cpu
      choice%predicted(i) = predicted_run(run, choice%t_probe, sc%scene%t_end)
    end associate
    call keep_least(choice, i)
  end subroutine probe

  !> Method `method` of sc (from the integrator settings `asked`) run on a copy of the
  !> model from the state x at t0 over t_len: `run` holds its stepper and model where it
  !> stopped, its CPU and pace, and (dt_rows > 0) the states of the rows every dt_rows from
  !> 0 it passed. `failure` says why it stopped early: an error, more than max_steps steps,
  !> more CPU in its steps than `cap`, far_margin times the CPU the fastest probe's steps
  !> (`pace`) took to reach the same time, or past a quarter of t_len a mean CPU rate above
  !> `most`; the run is then not kept.
  subroutine race(sc, asked, method, model, t0, x, t_len, cap, pace, most, dt_rows, run, failure)
    type(scene_t), intent(in) :: sc
    type(integrator_spec), intent(in) :: asked
    integer, intent(in) :: method
    type(model_t), intent(in) :: model
    real(dp), intent(in) :: t0, x(:), t_len, cap, pace(:), most, dt_rows
    type(probe_run), intent(inout) :: run
    character(len=*), intent(out) :: failure
    type(error_type), allocatable :: error
    type(scene_t) :: trial
    real(dp) :: cpu0, cpu, h0, t
    integer :: k_row, steps, j
    type(step_counts) :: done
    failure = ''
    run = probe_run()
    trial = sc
    call set_method(trial, asked, method)
    cpu0 = thread_cpu_time()
    allocate(run%model, source=model)
    run%nr = -1
    if (dt_rows > 0.0_dp) allocate(run%rows(size(x), 16))
    if (dt_rows > 0.0_dp) run%nr = 0
    call make_stepper(trial, run%model, x, run%st, h0, error)
    if (.not. allocated(error)) call run%st%start(run%model, t0, x, h0, error)
    run%making = thread_cpu_time() - cpu0
    k_row = 1; steps = 0; j = 1
    do while (.not. allocated(error))
      t = run%st%time() - t0
      if (run%nr >= 0) call dense_rows(dt_rows, min(run%st%time(), sc%scene%t_end) + 1.0e-9_dp*sc%integrator%h_slow, &
        & run, k_row)
      cpu = thread_cpu_time() - cpu0
      do while (j <= n_pace .and. t >= j*t_len/n_pace)
        run%pace(j) = cpu - run%making; j = j + 1
      end do
      if (run%cpu_half < 0.0_dp .and. t >= 0.5_dp*t_len) then
        run%cpu_half = cpu; run%t_half = t
      end if
      if (t >= t_len) exit
      if (cpu - run%making > cap .or. (steps >= far_steps .and. (cpu - run%making)/far_margin > &
        & pace(pace_index(t, t_len))) .or. (t >= 0.25_dp*t_len .and. cpu > most*t)) then
        failure = 'stopped at t = ' // fmt(run%st%time()) // ' s: slower than the fastest probe'
        run%cpu = cpu; run%t_run = t
        call forget(run); return
      end if
      call run%st%advance(run%model, error)
      steps = steps + 1
      done = run%st%counts()
      if (.not. allocated(error) .and. done%steps_fast > sc%integrator%max_steps) &
        & call fatal_error(error, 'at t = ' // fmt(run%st%time()) // ' s: the probe took more than max_steps = ' // &
        & itoa(sc%integrator%max_steps) // ' steps')
    end do
    if (allocated(error)) then
      failure = error%message
      call forget(run); return
    end if
    run%cpu = thread_cpu_time() - cpu0
    run%t_run = run%st%time() - t0
  end subroutine race

  !> How much dearer than candidate `run` (CPU rate rates(run)) the next cheapest was: its
  !> rate over run's (huge when every other failed). A stopped probe's rate is its mean up
  !> to its stop, its start's small steps included: it counts as at most race_margin
  !> dearer, the margin that stopped it (on the flexible chain 'adams' and 'response' both
  !> stopped in 1 of 25 starts under load, and their means put the lead past any growth,
  !> so no review came).
  pure real(dp) function lead_of(rates, run, stopped) result(lead)
    real(dp), intent(in) :: rates(:)
    integer, intent(in) :: run
    logical, intent(in) :: stopped(:)
    integer :: i
    lead = huge(1.0_dp)
    do i = 1, size(rates)
      if (i == run .or. rates(i) == huge(1.0_dp)) cycle
      lead = min(lead, merge(min(rates(i)/rates(run), race_margin), rates(i)/rates(run), stopped(i)))
    end do
  end function lead_of

  !> The baseline after a review that kept the running method (window rate `rate`, the
  !> running method's lead over the others as the review probed them): the window's rate
  !> when it still probed the cheapest (a growth every method shares), else the baseline
  !> as it was, so that the next dear windows call the next review.
  pure real(dp) function baseline_after_review(base_rate, rate, lead) result(base)
    real(dp), intent(in) :: base_rate, rate, lead
    base = merge(rate, base_rate, lead >= 1.0_dp)
  end function baseline_after_review

  !> Whether a probe's failure says it was stopped (slower than the fastest; race writes it).
  elemental logical function was_stopped(failure)
    character(len=*), intent(in) :: failure
    was_stopped = len(failure) >= 7
    if (was_stopped) was_stopped = failure(1:7) == 'stopped'
  end function was_stopped

  !> A probe's mean CPU rate over what it ran, finished or stopped (its stepper's making
  !> included); huge when it failed.
  pure real(dp) function mean_rate(run, failure) result(r)
    type(probe_run), intent(in) :: run
    character(len=*), intent(in) :: failure
    r = huge(1.0_dp)
    if ((len_trim(failure) == 0 .or. was_stopped(failure)) .and. run%t_run > 0.0_dp) r = run%cpu/run%t_run
  end function mean_rate

  !> The pace entry at or after the time t into a probe of length t_len.
  pure integer function pace_index(t, t_len) result(j)
    real(dp), intent(in) :: t, t_len
    j = min(n_pace, max(1, ceiling(n_pace*t/t_len)))
  end function pace_index

  !> Of the finished probes 1..i only the one of least predicted CPU is kept (each holds a
  !> copy of the model and a stepper: the memory check, build.f90 run_bytes, counts one
  !> besides the probe running), and its pace is the one later probes race.
  subroutine keep_least(choice, i)
    type(method_choice_t), intent(inout) :: choice
    integer, intent(in) :: i
    integer :: j, least
    least = minloc(choice%predicted(1:i), 1)
    choice%pace = choice%runs(least)%pace
    do j = 1, i
      if (j /= least) call forget(choice%runs(j))
    end do
  end subroutine keep_least

  !> A probe's predicted run to t_end (the probe ran over [0, t_probe]): its CPU, and its
  !> CPU rate over its second half scaled to the rest of the run; a probe of one or two
  !> steps (no second half to speak of): its CPU scaled.
  pure real(dp) function predicted_run(run, t_probe, t_end) result(p)
    type(probe_run), intent(in) :: run
    real(dp), intent(in) :: t_probe, t_end
    if (run%cpu_half < 0.0_dp .or. run%t_run - run%t_half < 0.25_dp*t_probe) then
      p = run%cpu*t_end/run%t_run
    else
      p = run%cpu + cpu_rate(run)*(t_end - run%t_run)
    end if
  end function predicted_run

  !> A finished probe's CPU per simulated second over its second half (over all of it when
  !> it took one or two steps).
  pure real(dp) function cpu_rate(run) result(r)
    type(probe_run), intent(in) :: run
    if (run%cpu_half < 0.0_dp .or. run%t_run - run%t_half <= 0.0_dp) then
      r = run%cpu/run%t_run
    else
      r = (run%cpu - run%cpu_half)/(run%t_run - run%t_half)
    end if
  end function cpu_rate

  !> Whether a review may still come: the choice was probed (not a restart's, nor a scene
  !> with one candidate) and reviews are left.
  pure logical function reviewing(self)
    class(method_choice_t), intent(in) :: self
    reviewing = self%t_probe > 0.0_dp .and. self%reviews < max_reviews
  end function reviewing

  !> Whether the run, its stepper at time t, is at the end of a review window (none when no
  !> review may come; the first call from t_open on opens the first window).
  logical function review_due(self, t, t_end) result(due)
    class(method_choice_t), intent(inout) :: self
    real(dp), intent(in) :: t, t_end
    due = .false.
    if (.not. self%reviewing()) return
    if (self%t_window < 0.0_dp) then
      if (t < self%t_open) return
      self%t_window = t
      call self%restart_window(thread_cpu_time()); return
    end if
    due = t >= self%t_window + review_share*t_end
  end function review_due

  !> A window starts at the thread's CPU `cpu` (a window's end reading starts the next one:
  !> the clock is a system call, 0.5 us), its output calls and their CPU back to none.
  subroutine restart_window(self, cpu)
    class(method_choice_t), intent(inout) :: self
    real(dp), intent(in) :: cpu
    self%cpu_window = cpu; self%output = 0.0_dp
    self%n_out = 0; self%n_timed = 0
  end subroutine restart_window

  !> Whether the run's next output call is timed (one in `sampling`, drawn by a linear
  !> congruential generator: the same calls in every run); counted either way.
  logical function times_output(self) result(yes)
    class(method_choice_t), intent(inout) :: self
    self%draw = modulo(1103515245_int64*self%draw + 12345_int64, 2147483648_int64)
    yes = modulo(self%draw/65536_int64, int(sampling, int64)) == 0
    self%n_out = self%n_out + 1
    if (yes) self%n_timed = self%n_timed + 1
  end function times_output

  !> At the end of a review window (the run's stepper st on the model at its time): the
  !> window's rate measured (the baseline is the cheapest window's since the start or the
  !> last review: on the flexible chain the first window, in the start's vibration, cost
  !> 1.4x the cheapest, and the review came at 1.18 s instead of 0.70 s), and the
  !> candidates probed again when dear_windows windows in a row are dearer than the
  !> baseline by the threshold and the review pays. `switched`: another method takes
  !> over, set in sc (the caller starts its stepper where st stands).
  subroutine review(self, sc, model, st, switched)
    class(method_choice_t), intent(inout) :: self
    type(scene_t), intent(inout) :: sc
    type(model_t), intent(in) :: model
    class(stepper_t), intent(in) :: st
    logical, intent(out) :: switched
    real(dp) :: rate, cpu
    logical :: probed
    switched = .false.; probed = .false.
    cpu = thread_cpu_time()
    rate = cpu - self%cpu_window
    if (self%n_timed > 0) rate = rate - self%output*self%n_out/self%n_timed
    rate = rate/(st%time() - self%t_window)
    if (rate <= 0.0_dp) then     ! the sampled output's estimate beyond the window's CPU
      call self%restart_window(cpu); self%t_window = st%time(); return
    end if
    if (self%base_rate < 0.0_dp) then
      self%base_rate = rate
    else
      self%dear = merge(self%dear + 1, 0, rate > max(review_margin, switch_gain*self%lead)*self%base_rate)
      self%base_rate = min(self%base_rate, rate)
      probed = self%dear >= dear_windows .and. pays(self, rate, sc%scene%t_end - st%time())
      if (probed) call probe_again(self, sc, model, st, rate, switched)
    end if
    ! the next window starts after the review's probes, after the start's steps when another
    ! method took over
    self%t_window = merge(-1.0_dp, st%time(), switched)
    if (probed) cpu = thread_cpu_time()
    call self%restart_window(cpu)
  end subroutine review

  !> Whether a review can pay at the window's CPU rate with `rest` of the run left: what a
  !> method switch_gain times cheaper would save over the rest is `payback` times what the
  !> review costs
  !> (every candidate's stepper made again, as its making cost at the start, and probed at
  !> that rate). A cheap run (a tank's, whose three steppers cost a tenth of it) is not
  !> reviewed for a growth that every method shares.
  logical function pays(self, rate, rest)
    type(method_choice_t), intent(in) :: self
    real(dp), intent(in) :: rate, rest
    real(dp) :: cost
    cost = sum(self%making(1:self%n)) + self%n*rate*review_probe*self%t_probe
    pays = rest >= review_rest*self%t_probe .and. rate*rest*(1.0_dp - 1.0_dp/switch_gain) > payback*cost
  end function pays

  !> Every candidate probed from the state st has reached over t_probe (no rows), the
  !> running method first: another whose CPU rate over its probe's second half is
  !> switch_gain times below the running method's takes over (the review noted in the
  !> choice's report). The probes are compared with each other, not with the window (whose
  !> steps ran over another stretch of the motion). The running method's probe stops at 3
  !> times the CPU its steps took at the window's `rate` (its rate is then the window's), the
  !> others' at race_margin times the more of its steps' CPU and the window's over as long,
  !> or of a finished probe's.
  subroutine probe_again(self, sc, model, st, rate, switched)
    type(method_choice_t), intent(inout) :: self
    type(scene_t), intent(inout) :: sc
    type(model_t), intent(in) :: model
    class(stepper_t), intent(in) :: st
    real(dp), intent(in) :: rate
    logical, intent(out) :: switched
    real(dp) :: rates(max_candidates), bound(max_candidates), pace(n_pace), x(2*model%d%n), cap, t_len
    type(probe_run) :: run
    character(len=200) :: failure, failures(max_candidates)
    integer :: i, k, best
    self%reviews = self%reviews + 1
    call st%value_at(st%time(), x)
    rates = huge(1.0_dp); bound = huge(1.0_dp)
    pace = huge(1.0_dp)          ! a start's small steps are dearer than the running steps' pace
    t_len = review_probe*self%t_probe
    cap = 3.0_dp*rate*t_len
    do k = 0, self%n
      i = k
      if (k == 0) i = self%chosen
      if (k == self%chosen) cycle
      call race(sc, self%asked, self%method(i), model, st%time(), x, t_len, cap, pace, huge(1.0_dp), 0.0_dp, &
        & run, failure)
      bound(i) = mean_rate(run, failure); failures(i) = failure
      if (len_trim(failure) == 0) then
        rates(i) = cpu_rate(run); bound(i) = rates(i)
        if (k == 0) cap = race_margin*max(run%pace(n_pace), rate*t_len)
        if (k > 0) cap = min(cap, race_margin*run%pace(n_pace))
      else if (k == 0) then
        rates(i) = rate; bound(i) = rate; cap = race_margin*rate*t_len
      end if
      call forget(run)
    end do
    best = minloc(rates(1:self%n), 1)
    switched = best /= self%chosen .and. switch_gain*rates(best) < rates(self%chosen)
    call note_review(self, st%time(), rate/self%base_rate, rates, merge(best, 0, switched))
    self%dear = 0
    if (switched) then
      self%chosen = best; self%base_rate = -1.0_dp; self%t_open = st%time() + self%t_probe
    end if
    self%lead = lead_of(bound(1:self%n), self%chosen, was_stopped(failures(1:self%n)))
    if (.not. switched) then
      self%base_rate = baseline_after_review(self%base_rate, rate, self%lead); return
    end if
    call set_method(sc, self%asked, self%method(best))
  end subroutine probe_again

  !> A review in the choice's summary text and JSON: its time, the window's CPU rate over
  !> the baseline, the candidates' probe rates, the method that took over (0: none).
  subroutine note_review(self, t, growth, rates, switched_to)
    type(method_choice_t), intent(inout) :: self
    real(dp), intent(in) :: t, growth, rates(:)
    integer, intent(in) :: switched_to
    character(len=:), allocatable :: s, j
    integer :: i
    s = '; at t = ' // fmt(t) // ' s its CPU rate was ' // two_decimals(growth) // 'x its cheapest window''s; probes'' CPU ' // &
      & 'rates:'
    j = '{"t": ' // fmt(t) // ', "rate_growth": ' // fmt(growth) // ', "cpu_s_per_s": ['
    do i = 1, self%n
      s = s // ' ' // trim(self%label(i)) // ' ' // rate_text(rates(i)) // trim(merge(',', ' ', i < self%n))
      if (rates(i) == huge(1.0_dp)) then
        j = j // 'null'
      else
        j = j // fmt(rates(i))
      end if
      if (i < self%n) j = j // ', '
    end do
    if (switched_to > 0) then
      s = s // ', ' // trim(self%label(switched_to)) // ' took over'
      j = j // '], "took_over": "' // json_escape(trim(self%label(switched_to))) // '"}'
    else
      s = s // ', kept'
      j = j // '], "took_over": null}'
    end if
    if (.not. allocated(self%review_text)) then
      self%review_text = ''; self%review_json = ''
    end if
    self%review_text = self%review_text // s
    if (len(self%review_json) > 0) self%review_json = self%review_json // ', '
    self%review_json = self%review_json // j
  end subroutine note_review

  !> A CPU rate (s per simulated s) as ms per simulated s, or "stopped".
  function rate_text(r) result(s)
    real(dp), intent(in) :: r
    character(len=:), allocatable :: s
    if (r == huge(1.0_dp)) then
      s = 'stopped'
    else
      s = milliseconds(r) // '/s'
    end if
  end function rate_text

  !> The chosen candidate's probe moved to `run` (not allocated when the probe was not kept).
  subroutine take_chosen(self, run)
    class(method_choice_t), intent(inout) :: self
    type(probe_run), allocatable, intent(out) :: run
    if (self%chosen == 0) return
    if (.not. allocated(self%runs(self%chosen)%st)) return
    allocate(run)
    call move_alloc(self%runs(self%chosen)%st, run%st)
    call move_alloc(self%runs(self%chosen)%model, run%model)
    call move_alloc(self%runs(self%chosen)%rows, run%rows)
    run%nr = self%runs(self%chosen)%nr
  end subroutine take_chosen

  !> A probe that failed or stopped is not kept.
  subroutine forget(run)
    type(probe_run), intent(inout) :: run
    if (allocated(run%st)) deallocate(run%st)
    if (allocated(run%model)) deallocate(run%model)
    if (allocated(run%rows)) deallocate(run%rows)
  end subroutine forget

  !> The dense output of the rows every dt (every step when dt is 0: not kept) up to the
  !> time t_last (the time the probe's stepper has reached, within the run, plus the run's
  !> tolerance on output times), from row k on (k advanced past them), kept in the probe's
  !> rows up to max_probe_rows; beyond, the rows are neither evaluated nor kept (nr = -1).
  subroutine dense_rows(dt, t_last, run, k)
    real(dp), intent(in) :: dt, t_last
    type(probe_run), intent(inout) :: run
    integer, intent(inout) :: k
    real(dp), allocatable :: grown(:, :)
    integer :: stat
    if (dt <= 0.0_dp) then
      call run%st%value_at(run%st%time(), run%rows(:, 1)); run%nr = -1; return
    end if
    do while (k*dt <= t_last .and. run%nr >= 0)
      if (k > size(run%rows, 2)) then
        allocate(grown(size(run%rows, 1), min(2*size(run%rows, 2), max_probe_rows)), stat=stat)
        if (k > max_probe_rows .or. stat /= 0) then
          run%nr = -1; exit
        end if
        grown(:, 1:k-1) = run%rows(:, 1:k-1)
        call move_alloc(grown, run%rows)
      end if
      call run%st%value_at(k*dt, run%rows(:, k))
      run%nr = k
      k = k + 1
    end do
  end subroutine dense_rows

  !> The method of a run of method 'auto' continued from the checkpoint `path`: the one
  !> whose stepper wrote it, set in sc (a file read_checkpoint refuses is refused here).
  subroutine method_of_checkpoint(sc, path, choice, error)
    type(scene_t), intent(inout) :: sc
    character(len=*), intent(in) :: path
    type(method_choice_t), intent(out) :: choice
    type(error_type), allocatable, intent(out) :: error
    character(len=:), allocatable :: name
    name = checkpoint_stepper(path, error); if (allocated(error)) return
    select case (name)
    case ('exponential')
      call add_candidate(choice, sc, 2)
    case ('response')
      call add_candidate(choice, sc, 3)
    case ('adams', 'single')
      call add_candidate(choice, sc, 1)
    case default
      call fatal_error(error, path // ": the checkpoint was written by the '" // name // "' stepper, which " // &
        & "method 'auto' never chooses: continue it with the scene's method set as it ran")
      return
    end select
    choice%chosen = 1; choice%first = 1
    choice%asked = asked_of(sc)
    call set_method(sc, choice%asked, choice%method(1))
    choice%reason = 'the method the checkpoint was written with'
  end subroutine method_of_checkpoint

  !> One line for the run's summary: "auto: multirate 'exponential', error_norm 'amplitude'
  !> (least CPU over the probe, 0 to 0.05 s: single-rate 'adams' 4.1 ms, ...; at t = 0.7 s
  !> its CPU rate was 1.52x its cheapest window's, probes: ..., single-rate 'adams' took
  !> over)".
  function choice_summary(self) result(s)
    class(method_choice_t), intent(in) :: self
    character(len=:), allocatable :: s
    integer :: i
    s = 'auto: ' // trim(self%label(self%first)) // ", error_norm '" // trim(self%asked%error_norm) // "' (" // &
      & self%reason
    if (self%t_probe > 0.0_dp) then
      s = s // '; probes from 0 to ' // fmt(self%t_probe) // ' s:'
      do i = 1, self%n
        s = s // ' ' // trim(self%label(i)) // ' ' // probe_text(self, i) // trim(merge(',', ' ', i < self%n))
      end do
    end if
    if (allocated(self%review_text)) s = s // self%review_text
    s = s // ')'
  end function choice_summary

  function probe_text(self, i) result(s)
    class(method_choice_t), intent(in) :: self
    integer, intent(in) :: i
    character(len=:), allocatable :: s
    if (self%failure(i) == left_out_note) then
      s = 'left out'
    else if (len_trim(self%failure(i)) > 0) then
      s = merge('stopped', 'failed ', was_stopped(self%failure(i)))
      s = trim(s)
    else
      s = milliseconds(self%cpu(i)) // ', run ' // milliseconds(self%predicted(i))
    end if
  end function probe_text

  !> A CPU time t (s) in ms, to 0.01 ms ("12.34 ms").
  function milliseconds(t) result(s)
    real(dp), intent(in) :: t
    character(len=:), allocatable :: s
    s = two_decimals(1.0e3_dp*t) // ' ms'
  end function milliseconds

  !> x (at most 1e12) to two decimals ("0.25", "12.34").
  function two_decimals(x) result(s)
    real(dp), intent(in) :: x
    character(len=:), allocatable :: s
    character(len=32) :: buf
    write(buf, '(f0.2)') min(x, 1.0e12_dp)
    if (buf(1:1) == '.') buf = '0' // buf(1:len(buf) - 1)
    s = trim(buf)
  end function two_decimals

  !> The JSON member "method_choice": {...}, with its comma and line: the first choice, its
  !> probes, the reviews, and the method the run ended with.
  function choice_json(self) result(s)
    class(method_choice_t), intent(in) :: self
    character(len=:), allocatable :: s
    integer :: i
    s = '  "method_choice": {"chosen": "' // json_escape(trim(self%label(self%first))) // '", "reason": "' // &
      & json_escape(self%reason) // '", "probe_t_end": ' // fmt(self%t_probe) // ', "candidates": ['
    do i = 1, self%n
      s = s // '{"method": "' // json_escape(trim(self%label(i))) // '", "probe_cpu_s": '
      if (len_trim(self%failure(i)) > 0 .or. self%t_probe == 0.0_dp) then
        s = s // 'null, "predicted_cpu_s": null'
      else
        s = s // fmt(self%cpu(i)) // ', "predicted_cpu_s": ' // fmt(self%predicted(i))
      end if
      s = s // ', "failure": "' // json_escape(trim(self%failure(i))) // '"}' // trim(merge(', ', '  ', i < self%n))
    end do
    s = s // '], "reviews": ['
    if (allocated(self%review_json)) s = s // self%review_json
    s = s // '], "ended_with": "' // json_escape(trim(self%label(self%chosen))) // '"},' // new_line('a')
  end function choice_json
end module pymr_driver_method_choice
