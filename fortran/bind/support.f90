!> Helpers of the binding layer that f2py need not see.
module pymr_bind_support
  use pymr_env_kinds, only : dp
  use pymr_env_error, only : error_type, error_kind
  use pymr_env_text, only : printable
  implicit none
  private
  public :: report
contains
  !> Copy an error (if any) into a status (0 ok, 1 bad input, 2 failed run), a message and
  !> its structured fields: `detail` holds one 'name=value' per field (kind, group, item,
  !> fault, stable_step, stable_ratio), separated by achar(30); empty when there is no error
  !> (the test hooks pass none).
  subroutine report(error, stat, message, detail)
    type(error_type), allocatable, intent(in) :: error
    integer, intent(out) :: stat
    character(len=*), intent(out) :: message
    character(len=*), intent(out), optional :: detail
    character(len=32) :: step, ratio
    stat = 0; message = ''
    if (present(detail)) detail = ''
    if (.not. allocated(error)) return
    stat = error%stat; message = printable(error%message, len(message))
    if (.not. present(detail)) return
    write(step, '(es25.17e3)') error%stable_step
    write(ratio, '(i0)') error%stable_ratio
    detail = 'kind=' // error_kind(error) // achar(30) // 'group=' // text(error%group) // achar(30) // &
      & 'item=' // text(error%item) // achar(30) // 'stable_step=' // trim(adjustl(step)) // achar(30) // &
      & 'stable_ratio=' // trim(ratio) // achar(30) // 'fault=' // text(error%fault)
  end subroutine report

  !> An optional text field's value as it may leave the kernel ('' when unset).
  pure function text(field) result(s)
    character(len=:), allocatable, intent(in) :: field
    character(len=:), allocatable :: s
    s = ''
    if (allocated(field)) s = printable(field)
  end function text
end module pymr_bind_support
