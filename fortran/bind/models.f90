!> Models kept open between binding calls: a handle is an index here. Every binding entry
!> point that works on a built model takes a handle (pymr_model_open builds one from a
!> scene's text); per handle the registry keeps the scene and the model as built.
!>
!> The model functions (terms, accelerations, modes, the initial state ...) each work on a
!> copy of the model as built (`scratch`), so that whatever they change in it (work arrays,
!> counters, the multirate partition, the loops' assembly) changes nothing a later call on
!> the handle returns: each call gives what a model built afresh for it gives. The
!> evaluations driven from Python (pymr_model_rhs, as scipy's integrators call it many
!> times, and the drawing's markers and frames) work on one copy kept per handle (`live`,
!> made at its first use), whose evaluation count goes on from call to call.
module pymr_bind_models
  use pymr_env_error, only : error_type, fatal_error
  use pymr_model_scene, only : scene_t
  use pymr_model, only : model_t
  implicit none
  private
  public :: open_model_t, open_models, open_flags, check_handle, check_handle_n, check_handle_count, open_slot, close_slot, scratch, live_model

  !> One open model: its scene, the model as built, and the copy Python's evaluations drive
  !> (all unallocated in a free slot).
  type :: open_model_t
    type(scene_t), allocatable :: sc
    type(model_t), allocatable :: built, live
  end type open_model_t

  type(open_model_t), allocatable, target :: open_models(:)
  logical, allocatable :: open_flags(:)
contains
  !> An error unless `handle` names an open model.
  subroutine check_handle(handle, error)
    integer, intent(in) :: handle
    type(error_type), allocatable, intent(out) :: error
    if (.not. allocated(open_flags)) then
      call fatal_error(error, 'no open model')
    else if (handle < 1 .or. handle > size(open_flags)) then
      call fatal_error(error, 'no open model with this handle')
    else if (.not. open_flags(handle)) then
      call fatal_error(error, 'the model of this handle is closed')
    end if
  end subroutine check_handle

  !> check_handle, and an error unless the open model has `n` coordinates (the length of
  !> the caller's q).
  subroutine check_handle_n(handle, n, error)
    integer, intent(in) :: handle, n
    type(error_type), allocatable, intent(out) :: error
    call check_handle(handle, error)
    if (allocated(error)) return
    if (open_models(handle)%built%d%n /= n) call fatal_error(error, 'q has the wrong length')
  end subroutine check_handle_n

  !> check_handle_n, and an error unless `given` (the caller's count `name`) is the open
  !> model's number of `what`: 'bodies', 'joints' (the loops' cut joints included) or
  !> 'markers'.
  subroutine check_handle_count(handle, n, name, what, given, error)
    integer, intent(in) :: handle, n, given
    character(*), intent(in) :: name, what
    type(error_type), allocatable, intent(out) :: error
    integer :: count
    call check_handle_n(handle, n, error)
    if (allocated(error)) return
    associate (d => open_models(handle)%built%d)
      select case (what)
      case ('bodies'); count = d%nb
      case ('joints'); count = d%nb - 1 + d%cuts%n
      case default; count = d%markers%n
      end select
    end associate
    if (given /= count) call fatal_error(error, name // ' is not the number of ' // what)
  end subroutine check_handle_count

  !> A copy of the model of `handle` as built, for one call of a model function (with
  !> check_handle_n's errors; `n` absent: any number of coordinates).
  subroutine scratch(handle, model, error, n)
    integer, intent(in) :: handle
    type(model_t), intent(out) :: model
    type(error_type), allocatable, intent(out) :: error
    integer, intent(in), optional :: n
    if (present(n)) then
      call check_handle_n(handle, n, error)
    else
      call check_handle(handle, error)
    end if
    if (.not. allocated(error)) model = open_models(handle)%built
  end subroutine scratch

  !> The copy of the model of `handle` that Python's evaluations drive, made at its first use
  !> (the handle must be open).
  function live_model(handle) result(model)
    integer, intent(in) :: handle
    type(model_t), pointer :: model
    if (.not. allocated(open_models(handle)%live)) allocate(open_models(handle)%live, source=open_models(handle)%built)
    model => open_models(handle)%live
  end function live_model

  !> A free slot of the table, its scene and model allocated for the build (the table grown
  !> when every slot is taken: each open model keeps its handle).
  integer function open_slot() result(k)
    type(open_model_t), allocatable :: grown(:)
    logical, allocatable :: flags(:)
    if (.not. allocated(open_models)) then
      allocate(open_models(4), open_flags(4))
      open_flags = .false.
    end if
    do k = 1, size(open_flags)
      if (.not. open_flags(k)) exit
    end do
    if (k > size(open_flags)) then
      allocate(grown(2*size(open_models)), flags(2*size(open_flags)))
      flags = .false.
      grown(1:size(open_models)) = open_models
      flags(1:size(open_flags)) = open_flags
      call move_alloc(grown, open_models)
      call move_alloc(flags, open_flags)
    end if
    call close_slot(k)
    allocate(open_models(k)%sc, open_models(k)%built)
  end function open_slot

  !> Release the open model of `handle` (nothing when it names none).
  subroutine close_slot(handle)
    integer, intent(in) :: handle
    if (.not. allocated(open_flags)) return
    if (handle < 1 .or. handle > size(open_flags)) return
    if (allocated(open_models(handle)%sc)) deallocate(open_models(handle)%sc)
    if (allocated(open_models(handle)%built)) deallocate(open_models(handle)%built)
    if (allocated(open_models(handle)%live)) deallocate(open_models(handle)%live)
    open_flags(handle) = .false.
  end subroutine close_slot
end module pymr_bind_models
