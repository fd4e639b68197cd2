!> The run's settings in its statistics file ("integrator": {...}), generated from the
!> &integrator item table: a new item appears there without code here.
module pymr_driver_settings_json
  use pymr_env_kinds, only : dp
  use pymr_env_item_table, only : item_table, item_t, t_real, t_integer, t_logical, t_string, is_unset
  use pymr_env_text, only : itoa, json_escape, json_number
  use pymr_model_scene, only : scene_t, describe_group
  implicit none
  private
  public :: settings_json

contains

  !> Every &integrator item as a JSON member ("name": value), then &scene t_end.
  function settings_json(sc) result(s)
    type(scene_t), target, intent(inout) :: sc
    character(len=:), allocatable :: s
    type(item_table) :: t
    integer :: m
    call describe_group(sc, 'integrator', 1, t)
    s = ''
    do m = 1, t%n
      s = s // '"' // trim(t%items(m)%name) // '": ' // json_value(t%items(m)) // ', '
    end do
    s = s // '"t_end": ' // json_real(sc%scene%t_end)
  end function settings_json

  !> An item's value in JSON: a number (a list for an array item: up to its first unset
  !> value when it takes a variable count), true or false, or a string.
  function json_value(it) result(s)
    type(item_t), intent(in) :: it
    character(len=:), allocatable :: s
    integer :: k
    select case (it%type)
    case (t_real)
      if (it%count == 1 .and. .not. it%variable) then
        s = json_real(it%r(1)); return
      end if
      s = ''
      do k = 1, size(it%r)
        if (it%variable .and. is_unset(it%r(k))) exit
        s = s // ', ' // json_real(it%r(k))
      end do
      if (len(s) > 0) s = s(3:)
      s = '[' // s // ']'
    case (t_integer)
      s = itoa(it%i)
    case (t_logical)
      s = trim(merge('true ', 'false', it%l))
    case default
      s = '"' // json_escape(trim(it%s)) // '"'
    end select
  end function json_value

  !> A real in JSON: ten significant digits, null when unset.
  function json_real(x) result(s)
    real(dp), intent(in) :: x
    character(len=:), allocatable :: s
    character(len=32) :: buf
    if (is_unset(x)) then
      s = 'null'; return
    end if
    s = json_number(x, 10)
  end function json_real

end module pymr_driver_settings_json
